/* The MPU-6050's samples for the lockstep fast path (included by fastpath.c: one translation unit).
 *
 * Why: at 1 kHz the IMU producer (emulators/chips/board.py ImuFeed.serve, over dlpf.ImuSampler.take,
 * sensor_models.ImuModel.sample_block and World.row_addresses) ran as Python once per FC cycle and
 * cost about as much as the rest of the cycle together; its arithmetic was C already.
 *
 * What: the steady case of ImuFeed.serve, step for step: the same float times (the running sum of the
 * period from the sampler's next_t, written back), the same history rows (World._slots' arithmetic), the
 * same C calls (rig_imu_measure, rig_lowpass_run, chip_push_imu: the emulators' library's own entry
 * points), the same DLPF gains and delays (LowPass's formulas). The normals stay numpy's, refilled by
 * the Python channel when C runs short. Anything else goes to the Python producer, which keeps its
 * state: a reset or a wake-up (its epoch or anchor moved), a new sample rate, the FIFO or the aux
 * master keeping every sample, a wait long enough to skip samples, and signal faults on accel or gyro.
 * Every case is decided before anything moves, so the Python producer takes over from the same state.
 *
 * The state shared with Python is read in place: next_t and World._k are cells (their addresses given
 * at setup). The feed's epoch, anchor, registers, period and filters change only in ImuFeed.serve, which
 * counts its calls in another cell; they are read again only when that count has moved (as attributes
 * every cycle they were about 1.5 k instructions of a 21 k cycle).
 */

typedef int32_t (*imu_measure_fn)(void *accel, void *gyro, int32_t n, const double *t, const double *const *rows,
                                  const int32_t cols[7], double die_offset, double *out);
typedef void (*lowpass_run_fn)(void *f, int32_t n, double *xs, int32_t stride, double a, int32_t depth);
typedef bool (*push_imu_fn)(chip_board *b, uint64_t valid_ns, const double v[7]);
typedef uint8_t (*peek_fn)(const chip_board *b, uint8_t chip, uint8_t reg);

#define IMU_BLOCK 64 /* emulators.native.BLOCK */

/* The world's history of plant-output rows (World._hist), as the samples' producers here read it */
typedef struct {
    char *hist;
    const int64_t *k;                        /* World._k's cell: the steps taken (World.k_addr) */
    int64_t k0, history, row_bytes, step_ns; /* World._k0, HISTORY, the row's bytes, World.step_ns */
} truth_ring;

/* World._k's cell (World.k_addr), or NULL: not a world (the caller's check says so) */
static int64_t *world_steps(PyObject *world)
{
    if (PyErr_Occurred())
        return NULL; /* (an earlier argument's error stands) */
    int64_t *k = address_attr(world, "k_addr");
    PyErr_Clear();
    return k;
}

/* World._slots and its row for sim time t (seconds) with the world at step k: the last step at or before
 * t, clamped to the history kept (one copy of this arithmetic for every producer in C) */
static const double *ring_row(const truth_ring *r, int64_t k, double t)
{
    int64_t oldest = k - r->history + 1 > r->k0 ? k - r->history + 1 : r->k0;
    int64_t slot = (int64_t)floor(t * 1e9 / (double)r->step_ns + 1e-9);
    slot = slot < oldest ? oldest : slot;
    slot = slot > k ? k : slot;
    return (const double *)(r->hist + (slot % r->history) * r->row_bytes);
}

/* world's cell and a[0..4]: k0, history, hist_addr, row_bytes, step_ns into r (errors: raised, checked by
 * the caller) */
static void ring_read(truth_ring *r, PyObject *world, PyObject *const *a)
{
    r->k = world_steps(world);
    r->k0 = PyLong_AsLongLong(a[0]);
    r->history = PyLong_AsLongLong(a[1]);
    r->hist = PyLong_AsVoidPtr(a[2]);
    r->row_bytes = PyLong_AsLongLong(a[3]);
    r->step_ns = PyLong_AsLongLong(a[4]);
}

static int ring_ok(const truth_ring *r)
{
    return r->hist && r->k && r->history > 0 && r->row_bytes > 0 && r->step_ns > 0;
}

typedef struct {
    int on;
    PyObject *feed, *sampler, *accel, *gyro, *accel_faults, *gyro_faults, *world; /* owned */
    void *accel_addr, *gyro_addr;
    const int32_t *cols;
    double die_offset;
    double *block;
    truth_ring ring;
    int64_t max_depth;
    uint8_t reg_config, reg_smplrt_div;
    double dlpf[8][4]; /* emulators.dlpf.DLPF: accel bw, accel delay, gyro bw, gyro delay */
    double *next_t;    /* the sampler's next_t (ImuSampler.next_t_addr) */
    /* what is kept of the feed, read after each of its Python serves (ImuFeed.serves_addr's count) */
    const int64_t *serves;
    int64_t serves_seen; /* -1: nothing read yet */
    long long epoch, anchor, cfg, div;
    double period;
    void *accel_f, *gyro_f;           /* the sampler's filters' C state (new after a reset) */
    PyObject *accel_held, *gyro_held; /* owned: those filters (their state stays while kept here) */
    uint64_t served;                  /* blocks of samples made here */
    imu_measure_fn measure;
    lowpass_run_fn lowpass;
    push_imu_fn push;
    peek_fn peek;
} imu_feed;

static PyObject *s_epoch, *s_anchor, *s_cfg, *s_div, *s_period, *s_accel_f, *s_gyro_f, *s_addr, *s_refill;

static void imu_free(imu_feed *f)
{
    PyObject *refs[] = { f->feed,         f->sampler,     f->world,      f->accel,    f->gyro,
                         f->accel_faults, f->gyro_faults, f->accel_held, f->gyro_held };
    for (size_t i = 0; i < sizeof refs / sizeof refs[0]; i++)
        Py_XDECREF(refs[i]);
    memset(f, 0, sizeof *f);
}

/* the address of a LowPass's C state (sampler._accel_f._addr): the filters are new after a reset. The
 * filter is held in *held while its address is kept, so the state stays where the address says. */
static int filter_addr(PyObject *sampler, PyObject *name, void **out, PyObject **held)
{
    PyObject *f = attr_get(sampler, name);
    if (!f)
        return -1;
    PyObject *a = attr_get(f, s_addr);
    Py_XSETREF(*held, f);
    if (!a)
        return -1;
    *out = PyLong_AsVoidPtr(a);
    Py_DECREF(a);
    return PyErr_Occurred() ? -1 : 0;
}

/* LowPass.run's delay in samples: max(0, round(delay / dt)) (round half to even, as Python's round) */
static int32_t depth_of(double delay, double dt)
{
    if (!(dt > 0.0))
        return 0;
    double d = nearbyint(delay / dt);
    return d > 0.0 ? (int32_t)d : 0;
}

/* LowPass._a: the gain of the exact first-order response over span seconds */
static double gain_of(double bw, double span) { return 1.0 - exp(-2.0 * M_PI * bw * span); }

/* 1: served; 0: for the Python producer (nothing done); -1: a Python error */
static int imu_serve(imu_feed *f, chip_board *b, const chip_need *need)
{
    uint32_t n = need->count;
    if (!f->on || need->keeps_all || n == 0 || n > IMU_BLOCK || PyList_GET_SIZE(f->accel_faults) ||
        PyList_GET_SIZE(f->gyro_faults))
        return 0;
    if (*f->serves != f->serves_seen) { /* (the Python producer ran: read again what it may have moved) */
        if (attr_ll(f->feed, s_epoch, &f->epoch) < 0 || attr_ll(f->feed, s_anchor, &f->anchor) < 0 ||
            attr_ll(f->feed, s_cfg, &f->cfg) < 0 || attr_ll(f->feed, s_div, &f->div) < 0 ||
            attr_double(f->feed, s_period, &f->period) < 0 ||
            filter_addr(f->sampler, s_accel_f, &f->accel_f, &f->accel_held) < 0 ||
            filter_addr(f->sampler, s_gyro_f, &f->gyro_f, &f->gyro_held) < 0) {
            f->serves_seen = -1;
            return -1;
        }
        f->serves_seen = *f->serves;
    }
    long long cfg = f->cfg;
    if (f->epoch != need->epoch || f->anchor != need->anchor || cfg != f->peek(b, CHIP_MPU, f->reg_config) ||
        f->div != f->peek(b, CHIP_MPU, f->reg_smplrt_div))
        return 0;
    double period = f->period, next_t = *f->next_t;
    int64_t k = *f->ring.k;
    const double *dl = f->dlpf[cfg & 0x07];
    int32_t a_depth = depth_of(dl[1], period), g_depth = depth_of(dl[3], period);
    if (a_depth > f->max_depth || g_depth > f->max_depth)
        return 0; /* the Python filter says why */
    /* ImuSampler.take: the times; World._slots: their history rows */
    double t[IMU_BLOCK];
    const double *rows[IMU_BLOCK];
    for (uint32_t i = 0; i < n; i++) {
        t[i] = next_t;
        next_t += period;
        rows[i] = ring_row(&f->ring, k, t[i]);
    }
    *f->next_t = next_t;
    /* ImuModel.sample_block: the model, refilling a channel's normals when it runs short */
    int32_t short_of;
    while (
        (short_of = f->measure(f->accel_addr, f->gyro_addr, (int32_t)n, t, rows, f->cols, f->die_offset, f->block))) {
        PyObject *want = PyLong_FromLong(6 * (long)n);
        if (!want)
            return -1;
        PyObject *r = PyObject_CallMethodObjArgs(short_of == 1 ? f->accel : f->gyro, s_refill, want, NULL);
        Py_DECREF(want);
        if (!r)
            return -1;
        Py_DECREF(r);
    }
    /* the DLPF */
    f->lowpass(f->accel_f, (int32_t)n, f->block, 7, gain_of(dl[0], period), a_depth);
    f->lowpass(f->gyro_f, (int32_t)n, f->block + 3, 7, gain_of(dl[2], period), g_depth);
    /* only the last instant's sample is encoded */
    f->push(b, need->t_ns + (uint64_t)(n - 1) * need->period_ns, f->block + 7 * (n - 1));
    f->served++;
    return 1;
}

/* setup_imu's work (fastpath.c): a[1..23] as setup_imu's arguments say; f is off until it succeeds */
static PyObject *imu_setup(imu_feed *f, PyObject *const *a)
{
    if (!PyList_Check(a[5]) || !PyList_Check(a[6]))
        return PyErr_Format(PyExc_TypeError, "setup_imu: the fault lists are lists");
    imu_free(f);
    PyObject **refs[] = { &f->feed, &f->sampler, &f->accel, &f->gyro, &f->accel_faults, &f->gyro_faults, &f->world };
    for (int i = 0; i < 7; i++) {
        Py_INCREF(a[1 + i]);
        *refs[i] = a[1 + i];
    }
    void **addrs[] = { &f->accel_addr, &f->gyro_addr, (void **)&f->next_t, (void **)&f->serves };
    PyObject *owners[] = { a[3], a[4], a[2], a[1] };
    const char *names[] = { "addr", "addr", "next_t_addr", "serves_addr" };
    for (int i = 0; i < 4 && !PyErr_Occurred(); i++)
        *addrs[i] = address_attr(owners[i], names[i]);
    f->serves_seen = -1;
    f->cols = PyLong_AsVoidPtr(a[8]);
    f->die_offset = PyFloat_AsDouble(a[9]);
    f->block = PyLong_AsVoidPtr(a[10]);
    PyObject *const ring_args[] = { a[11], a[12], a[13], a[14], a[16] };
    ring_read(&f->ring, f->world, ring_args);
    f->max_depth = PyLong_AsLongLong(a[15]);
    f->reg_config = (uint8_t)PyLong_AsLong(a[17]);
    f->reg_smplrt_div = (uint8_t)PyLong_AsLong(a[18]);
    PyObject *rows = PySequence_Fast(a[19], "setup_imu: dlpf is a sequence");
    if (rows && PySequence_Fast_GET_SIZE(rows) == 8) {
        for (int i = 0; i < 8 && !PyErr_Occurred(); i++) {
            PyObject *row = PySequence_Fast(PySequence_Fast_GET_ITEM(rows, i), "setup_imu: a dlpf row");
            if (!row)
                break;
            for (int j = 0; j < 4 && j < PySequence_Fast_GET_SIZE(row); j++)
                f->dlpf[i][j] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(row, j));
            Py_DECREF(row);
        }
    } else if (rows) {
        PyErr_SetString(PyExc_ValueError, "setup_imu: dlpf has 8 rows");
    }
    Py_XDECREF(rows);
    f->measure = (imu_measure_fn)PyLong_AsVoidPtr(a[20]);
    f->lowpass = (lowpass_run_fn)PyLong_AsVoidPtr(a[21]);
    f->push = (push_imu_fn)PyLong_AsVoidPtr(a[22]);
    f->peek = (peek_fn)PyLong_AsVoidPtr(a[23]);
    if (PyErr_Occurred()) {
        imu_free(f);
        return NULL;
    }
    if (!f->accel_addr || !f->gyro_addr || !f->next_t || !f->serves || !f->cols || !f->block || !ring_ok(&f->ring) ||
        !f->measure || !f->lowpass || !f->push || !f->peek) {
        imu_free(f);
        return PyErr_Format(PyExc_ValueError, "setup_imu: addresses, history, rows and step must be set");
    }
    f->on = 1;
    Py_RETURN_NONE;
}
