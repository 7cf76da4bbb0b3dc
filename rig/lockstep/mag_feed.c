/* The HMC5883L's samples for the lockstep fast path (included by fastpath.c after its fast_state: one
 * translation unit).
 *
 * Why: the magnetometer's producer (emulators/chips/board.py MagFeed.serve over sensor_models.MagModel
 * and World.truth) ran as Python at every measurement the FC read (75 Hz), about 7 k instructions per FC
 * cycle of a flight: more than the I2C transfer that asked for it. Its arithmetic was C already.
 *
 * What: the steady case of MagFeed.serve, step for step: the same float times (the period added once per
 * measurement since the last, from MagFeed._next_t, written back with _index), the same history row
 * (World._slots' arithmetic, as imu_feed.c), the disturbance of a scenario's window or none, the same C
 * call for the errors and noise (rig_channel_measure, the emulators' library's own entry point, its
 * normals refilled by the Python channel when short) and chip_push_mag. Everything else stays with the
 * Python producer, which keeps its state: a source or disturbance replaced since setup, a new anchor (a restart
 * of the measurement clock), a signal fault on the magnetometer, and a disturbance that is not a scenario's
 * window.
 */

typedef int32_t (*channel_measure_fn)(void *c, int32_t n, const double *t, const double *truth, const double *temp,
                                      double *out);
typedef bool (*push_mag_fn)(chip_board *b, uint64_t valid_ns, const double field[3]);

struct mag_feed {
    int on;
    PyObject *feed, *channel, *faults, *world; /* owned: MagFeed, its model's _Channel, FaultSet.faults, World */
    PyObject *model, *disturbance;             /* owned: the feed's source and its disturbance at setup */
    void *channel_addr;
    truth_ring ring;
    int32_t cols[3];                    /* mag_x, mag_y, mag_z in a history row */
    double rates_hz[8];                 /* hmc5883l.RATES_HZ by CRA.DO */
    double dist[3], dist_from, dist_to; /* the scenario's disturbance (body, gauss) in [from, to) */
    uint8_t reg_cra;
    channel_measure_fn measure;
    push_mag_fn push;
    peek_fn peek;
    uint64_t served; /* measurements made here */
};

static PyObject *s_mag_index, *s_mag_next_t, *s_source, *s_disturbance;

static void mag_free(mag_feed *f)
{
    PyObject *refs[] = { f->feed, f->channel, f->faults, f->world, f->model, f->disturbance };
    for (size_t i = 0; i < sizeof refs / sizeof refs[0]; i++)
        Py_XDECREF(refs[i]);
    memset(f, 0, sizeof *f);
}

static void mag_release(mag_feed *f)
{
    if (f)
        mag_free(f);
    PyMem_Free(f);
}

/* 1: served; 0: for the Python producer (nothing done); -1: a Python error */
static int mag_serve(mag_feed *f, chip_board *b, const chip_need *need)
{
    if (!f || !f->on || PyList_GET_SIZE(f->faults))
        return 0;
    int same = same_attr(f->feed, s_source, f->model);
    same = same > 0 ? same_attr(f->model, s_disturbance, f->disturbance) : same;
    if (same <= 0)
        return same;
    long long anchor, index, k;
    double next_t;
    if (attr_ll(f->feed, s_anchor, &anchor) < 0 || attr_ll(f->feed, s_mag_index, &index) < 0 ||
        attr_double(f->feed, s_mag_next_t, &next_t) < 0)
        return -1;
    k = *f->ring.k;
    if (anchor != (long long)need->anchor)
        return 0;
    double period = 1.0 / f->rates_hz[(f->peek(b, CHIP_HMC, f->reg_cra) >> 2) & 0x7];
    for (; index < (long long)need->count; index++)
        next_t += period;
    /* World._slots and MagModel.__call__ */
    const double *row = ring_row(&f->ring, k, next_t);
    int in = f->dist_from <= next_t && next_t < f->dist_to;
    double field[3], out[3], temperature = 25.0;
    for (int i = 0; i < 3; i++)
        field[i] = row[f->cols[i]] + (in ? f->dist[i] : 0.0);
    while (f->measure(f->channel_addr, 1, &next_t, field, &temperature, out)) {
        PyObject *want = PyLong_FromLong(6);
        if (!want)
            return -1;
        PyObject *r = PyObject_CallMethodObjArgs(f->channel, s_refill, want, NULL);
        Py_DECREF(want);
        if (!r)
            return -1;
        Py_DECREF(r);
    }
    PyObject *vi = PyLong_FromLongLong(index), *vt = PyFloat_FromDouble(next_t);
    int bad = !vi || !vt || attr_set(f->feed, s_mag_index, vi) || attr_set(f->feed, s_mag_next_t, vt);
    Py_XDECREF(vi);
    Py_XDECREF(vt);
    if (bad)
        return -1;
    f->push(b, need->t_ns, out);
    f->served++;
    return 1;
}

/* setup_mag's work: a[1..18] as setup_mag's arguments say; f is off until it succeeds */
static PyObject *mag_setup(mag_feed *f, PyObject *const *a)
{
    if (!PyList_Check(a[3]))
        return PyErr_Format(PyExc_TypeError, "setup_mag: the fault list is a list");
    if ((!s_mag_index && !(s_mag_index = PyUnicode_InternFromString("_index"))) ||
        (!s_mag_next_t && !(s_mag_next_t = PyUnicode_InternFromString("_next_t"))) ||
        (!s_source && !(s_source = PyUnicode_InternFromString("source"))) ||
        (!s_disturbance && !(s_disturbance = PyUnicode_InternFromString("disturbance"))))
        return NULL;
    mag_free(f);
    PyObject **refs[] = { &f->feed, &f->channel, &f->faults, &f->world };
    for (int i = 0; i < 4; i++) {
        Py_INCREF(a[1 + i]);
        *refs[i] = a[1 + i];
    }
    f->model = attr_get(f->feed, s_source);
    f->disturbance = f->model ? attr_get(f->model, s_disturbance) : NULL;
    f->channel_addr = address_attr(a[2], "addr");
    ring_read(&f->ring, f->world, a + 5);
    f->reg_cra = (uint8_t)PyLong_AsLong(a[10]);
    double *into[] = { f->rates_hz, f->dist };
    Py_ssize_t sizes[] = { 8, 3 }, cols = 3;
    PyObject *seqs[] = { a[11], a[13] };
    PyObject *col_seq = PySequence_Fast(a[12], "setup_mag: cols is a sequence");
    for (int i = 0; col_seq && i < (int)cols && i < PySequence_Fast_GET_SIZE(col_seq); i++)
        f->cols[i] = (int32_t)PyLong_AsLong(PySequence_Fast_GET_ITEM(col_seq, i));
    if (col_seq && PySequence_Fast_GET_SIZE(col_seq) != cols && !PyErr_Occurred())
        PyErr_SetString(PyExc_ValueError, "setup_mag: cols has 3 columns");
    Py_XDECREF(col_seq);
    for (int s = 0; s < 2 && !PyErr_Occurred(); s++) {
        PyObject *q = PySequence_Fast(seqs[s], "setup_mag: rates and the disturbance are sequences");
        if (q && PySequence_Fast_GET_SIZE(q) != sizes[s])
            PyErr_SetString(PyExc_ValueError, "setup_mag: 8 rates and 3 disturbance components");
        for (Py_ssize_t i = 0; q && !PyErr_Occurred() && i < sizes[s]; i++)
            into[s][i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(q, i));
        Py_XDECREF(q);
    }
    f->dist_from = PyFloat_AsDouble(a[14]);
    f->dist_to = PyFloat_AsDouble(a[15]);
    f->measure = (channel_measure_fn)PyLong_AsVoidPtr(a[16]);
    f->push = (push_mag_fn)PyLong_AsVoidPtr(a[17]);
    f->peek = (peek_fn)PyLong_AsVoidPtr(a[18]);
    if (PyErr_Occurred()) {
        mag_free(f);
        return NULL;
    }
    int rates_ok = 1;
    for (int i = 0; i < 8; i++)
        rates_ok &= f->rates_hz[i] > 0.0;
    if (!f->channel_addr || !ring_ok(&f->ring) || !rates_ok || !f->measure || !f->push || !f->peek) {
        mag_free(f);
        return PyErr_Format(PyExc_ValueError, "setup_mag: addresses, history, rates and step must be set");
    }
    f->on = 1;
    Py_RETURN_NONE;
}

/* setup_mag(state, feed, channel, faults, world, k0, history, hist_addr, row_bytes, step_ns, reg_cra, rates_hz
 *           (8), cols (mag_x, mag_y, mag_z), disturbance (3), disturbance_from, disturbance_to, measure_addr,
 *           push_addr, peek_addr): the magnetometer's samples in C from now on; channel is its model's
 * _Channel, faults its FaultSet's list */
static PyObject *fp_setup_mag(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 19)
        return PyErr_Format(PyExc_TypeError, "setup_mag takes 19 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    if (!s)
        return NULL;
    if (!s->mag && !(s->mag = PyMem_Calloc(1, sizeof *s->mag)))
        return PyErr_NoMemory();
    return mag_setup(s->mag, a);
}
