/* The MS5611's conversion results for the lockstep fast path (included by fastpath.c after its
 * fast_state: one translation unit).
 *
 * Why: the barometer's producer (emulators/chips/board.py BaroFeed.serve over sensor_models.BaroModel,
 * World.truth and ms5611.encode) ran as Python for every conversion the FC started (D1 and D2, about 80
 * a second each for the reference FC), about 7 k instructions per FC cycle of a flight.
 *
 * What: BaroFeed.serve step for step in its common case: the conversion's end time (the same float
 * operations), the truth row of that instant (World._slots' arithmetic, as imu_feed.c), BaroModel's
 * offset and drift, the clamps to the sensor's range (Python's min and max), and the exact inverse of
 * the datasheet compensation (ms5611.encode's integer mode: the same integer steps, with Python's floor
 * semantics for >> and //), then chip_push_baro. The temperature's D2 is searched once per temperature
 * and kept (ms5611.encode_temperature is cached likewise). Everything else stays with the Python
 * producer: a source replaced since setup, noise on the model or the conversion (numpy's generator), a signal
 * fault, the float encoding, a value outside the sensor's range (Python raises), and a PROM whose words do not
 * fit 16 bits.
 */

typedef bool (*push_baro_fn)(chip_board *b, uint64_t valid_ns, uint32_t d1, uint32_t d2);

struct baro_feed {
    int on;
    PyObject *feed, *model, *faults, *world; /* owned: BaroFeed, its BaroModel, FaultSet.faults, World */
    PyObject *prom_obj;                      /* owned: the PROM tuple prom[] was read from */
    int64_t prom[8];
    int64_t temp_key, temp_d2; /* the last temperature (0.01 °C) searched and its D2; key -1 << 40: none */
    truth_ring ring;
    int32_t cols[2];         /* pressure, temperature in a history row */
    double conversion[2][5]; /* ms5611.CONVERSION_TYPICAL, CONVERSION_MAX by OSR index */
    push_baro_fn push;
    uint64_t served; /* conversions made here */
};

static PyObject *s_prom, *s_timing, *s_encoding, *s_osr_noise, *s_offset_pa, *s_drift, *s_noise_pa, *s_max, *s_float;

static void baro_free(baro_feed *f)
{
    PyObject *refs[] = { f->feed, f->model, f->faults, f->world, f->prom_obj };
    for (size_t i = 0; i < sizeof refs / sizeof refs[0]; i++)
        Py_XDECREF(refs[i]);
    memset(f, 0, sizeof *f);
}

static void baro_release(baro_feed *f)
{
    if (f)
        baro_free(f);
    PyMem_Free(f);
}

/* Python's a // b for b > 0 (C's / truncates towards zero) */
static int64_t floor_div(int64_t a, int64_t b)
{
    int64_t q = a / b;
    return a % b < 0 ? q - 1 : q;
}

/* ms5611._terms: TEMP, OFF and SENS for a D2, second-order terms applied (>> of a negative number is
 * arithmetic with GCC: Python's floor) */
static void baro_terms(const int64_t *c, int64_t d2, int64_t *temp, int64_t *off, int64_t *sens)
{
    int64_t dt = d2 - c[5] * 256;
    *temp = 2000 + ((dt * c[6]) >> 23);
    *off = c[2] * 65536 + ((c[4] * dt) >> 7);
    *sens = c[1] * 32768 + ((c[3] * dt) >> 8);
    if (*temp < 2000) {
        int64_t t2 = (dt * dt) >> 31, low = (*temp - 2000) * (*temp - 2000);
        int64_t off2 = (5 * low) >> 1, sens2 = (5 * low) >> 2;
        if (*temp < -1500) {
            int64_t lower = (*temp + 1500) * (*temp + 1500);
            off2 += 7 * lower;
            sens2 += (11 * lower) >> 1;
        }
        *temp -= t2;
        *off -= off2;
        *sens -= sens2;
    }
}

static int64_t baro_temp_of(const int64_t *c, int64_t d2)
{
    int64_t temp, off, sens;
    baro_terms(c, d2, &temp, &off, &sens);
    return temp;
}

/* encode_temperature's first_at_least: the least D2 in 1 .. 2^24 - 2 whose TEMP is at least target */
static int64_t baro_first_at_least(const int64_t *c, int64_t target)
{
    int64_t lo = 1, hi = (1 << 24) - 2;
    while (lo < hi) {
        int64_t mid = (lo + hi) / 2;
        if (baro_temp_of(c, mid) >= target)
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* ms5611.encode_temperature */
static int64_t baro_encode_temperature(const int64_t *c, int64_t temp_centi)
{
    int64_t lo = baro_first_at_least(c, temp_centi);
    if (baro_temp_of(c, lo) != temp_centi) {
        int64_t below = baro_temp_of(c, lo - 1);
        if (lo > 1 && temp_centi - below <= baro_temp_of(c, lo) - temp_centi) {
            temp_centi = below;
            lo = baro_first_at_least(c, below);
        } else {
            temp_centi = baro_temp_of(c, lo);
        }
    }
    int64_t hi = baro_first_at_least(c, temp_centi + 1) - 1;
    return (lo + hi) / 2;
}

/* ms5611.encode_pressure: 1 with *d1 set; 0: for Python (SENS not positive, or too large for int64 here) */
static int baro_encode_pressure(const int64_t *c, int64_t d2, int64_t pressure_pa, int64_t *d1)
{
    int64_t temp, off, sens;
    baro_terms(c, d2, &temp, &off, &sens);
    int64_t a = off + pressure_pa * 32768;
    if (sens <= 0 || a > ((int64_t)1 << 40) || a < -((int64_t)1 << 40))
        return 0;
    int64_t d1_min = -floor_div(-a * 2097152, sens);
    int64_t d1_max = floor_div((a + 32768) * 2097152 - 1, sens);
    *d1 = floor_div(d1_min + d1_max, 2);
    return 1;
}

/* 1: the feed's PROM (read again only when it is another tuple) fits; 0: for Python; -1: error */
static int baro_prom(baro_feed *f)
{
    PyObject *prom = attr_get(f->feed, s_prom);
    if (!prom)
        return -1;
    if (prom == f->prom_obj) {
        Py_DECREF(prom);
        return 1;
    }
    Py_CLEAR(f->prom_obj);
    if (!PyTuple_Check(prom) || PyTuple_GET_SIZE(prom) != 8) {
        Py_DECREF(prom);
        return 0;
    }
    for (Py_ssize_t i = 0; i < 8; i++) {
        long v = PyLong_AsLong(PyTuple_GET_ITEM(prom, i));
        if (v == -1 && PyErr_Occurred()) {
            PyErr_Clear();
            v = -1;
        }
        if (v < 0 || v > 0xFFFF) {
            Py_DECREF(prom);
            return 0;
        }
        f->prom[i] = v;
    }
    f->prom_obj = prom; /* (the reference is kept) */
    f->temp_key = -((int64_t)1 << 40);
    return 1;
}

/* 1: served; 0: for the Python producer (nothing done); -1: a Python error */
static int baro_serve(baro_feed *f, chip_board *b, const chip_need *need)
{
    if (!f || !f->on || PyList_GET_SIZE(f->faults) || need->osr >= 5)
        return 0;
    int same = same_attr(f->feed, s_source, f->model);
    if (same <= 0)
        return same; /* (another source since setup_baro: Python's) */
    int osr_noise = attr_true(f->feed, s_osr_noise), noisy = attr_true(f->model, s_noise_pa);
    if (osr_noise < 0 || noisy < 0)
        return -1;
    if (osr_noise || noisy)
        return 0;
    PyObject *encoding = attr_get(f->feed, s_encoding), *timing = attr_get(f->feed, s_timing);
    int is_float = encoding ? PyObject_RichCompareBool(encoding, s_float, Py_EQ) : -1; /* (else integer) */
    int max = timing ? PyObject_RichCompareBool(timing, s_max, Py_EQ) : -1;
    Py_XDECREF(encoding);
    Py_XDECREF(timing);
    if (is_float < 0 || max < 0)
        return -1;
    int fits = is_float ? 0 : baro_prom(f);
    if (fits <= 0)
        return fits;
    double offset, drift;
    long long k;
    if (attr_double(f->model, s_offset_pa, &offset) < 0 || attr_double(f->model, s_drift, &drift) < 0)
        return -1;
    k = *f->ring.k;
    /* BaroFeed.serve's instant, World._slots' row, BaroModel.__call__, BaroFeed.words' clamps */
    double t = (double)need->anchor_ns * 1e-9 + f->conversion[max][need->osr];
    const double *row = ring_row(&f->ring, k, t);
    double p = row[f->cols[0]] + offset + drift * t, temp = row[f->cols[1]];
    p = 1000.0 > p ? 1000.0 : p;
    p = 120000.0 < p ? 120000.0 : p;
    temp = -40.0 > temp ? -40.0 : temp;
    temp = 85.0 < temp ? 85.0 : temp;
    if (!(1000.0 <= p && p <= 120000.0 && -40.0 <= temp && temp <= 85.0))
        return 0; /* (NaN: Python says why) */
    /* ms5611.encode, integer mode (round: half to even, as Python's) */
    int64_t temp_centi = (int64_t)nearbyint(100.0 * temp), d1;
    if (temp_centi != f->temp_key) {
        f->temp_d2 = baro_encode_temperature(f->prom, temp_centi);
        f->temp_key = temp_centi;
    }
    if (!baro_encode_pressure(f->prom, f->temp_d2, (int64_t)nearbyint(p), &d1))
        return 0;
    if (d1 < 0 || f->temp_d2 < 0)
        return 0; /* (Python's push raises) */
    f->push(b, need->t_ns, (uint32_t)d1, (uint32_t)f->temp_d2);
    f->served++;
    return 1;
}

/* setup_baro(state, feed, model, faults, world, k0, history, hist_addr, row_bytes, step_ns, cols (pressure,
 *            temperature), conversion (typical and max, 5 each), push_addr): the barometer's conversions
 * in C from now on; model is the feed's BaroModel, faults its FaultSet's list */
static PyObject *fp_setup_baro(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 13)
        return PyErr_Format(PyExc_TypeError, "setup_baro takes 13 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    if (!s)
        return NULL;
    if (!PyList_Check(a[3]))
        return PyErr_Format(PyExc_TypeError, "setup_baro: the fault list is a list");
    PyObject **names[] = { &s_prom,  &s_timing,   &s_encoding, &s_osr_noise, &s_offset_pa,
                           &s_drift, &s_noise_pa, &s_max,      &s_float };
    const char *texts[] = { "prom",           "timing",   "encoding", "osr_noise", "offset_pa",
                            "drift_pa_per_s", "noise_pa", "max",      "float" };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (!*names[i] && !(*names[i] = PyUnicode_InternFromString(texts[i])))
            return NULL;
    if (!s->baro && !(s->baro = PyMem_Calloc(1, sizeof *s->baro)))
        return PyErr_NoMemory();
    baro_feed *f = s->baro;
    baro_free(f);
    PyObject **refs[] = { &f->feed, &f->model, &f->faults, &f->world };
    for (int i = 0; i < 4; i++) {
        Py_INCREF(a[1 + i]);
        *refs[i] = a[1 + i];
    }
    ring_read(&f->ring, f->world, a + 5);
    PyObject *cols = PySequence_Fast(a[10], "setup_baro: cols is a sequence");
    PyObject *conv = PySequence_Fast(a[11], "setup_baro: conversion is a sequence");
    if (cols && conv && (PySequence_Fast_GET_SIZE(cols) != 2 || PySequence_Fast_GET_SIZE(conv) != 10))
        PyErr_SetString(PyExc_ValueError, "setup_baro: 2 columns and 10 conversion times");
    for (int i = 0; cols && conv && !PyErr_Occurred() && i < 10; i++) {
        if (i < 2)
            f->cols[i] = (int32_t)PyLong_AsLong(PySequence_Fast_GET_ITEM(cols, i));
        f->conversion[i / 5][i % 5] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(conv, i));
    }
    Py_XDECREF(cols);
    Py_XDECREF(conv);
    f->push = (push_baro_fn)PyLong_AsVoidPtr(a[12]);
    if (PyErr_Occurred()) {
        baro_free(f);
        return NULL;
    }
    if (!ring_ok(&f->ring) || !f->push) {
        baro_free(f);
        return PyErr_Format(PyExc_ValueError, "setup_baro: addresses, history and step must be set");
    }
    f->temp_key = -((int64_t)1 << 40);
    f->on = 1;
    Py_RETURN_NONE;
}

/* made_here(state): (the magnetometer's measurements, the barometer's conversions, the IMU's blocks of
 * samples) made here so far: a test's evidence that C made them */
static PyObject *fp_made_here(PyObject *self, PyObject *state)
{
    (void)self;
    fast_state *s = PyCapsule_GetPointer(state, "rig.lockstep");
    return s ? Py_BuildValue("(KKK)", (unsigned long long)(s->mag ? s->mag->served : 0),
                             (unsigned long long)(s->baro ? s->baro->served : 0), (unsigned long long)s->imu.served)
             : NULL;
}
