/* The emulators' C library as one CPython extension module, ``_rignative``: the sampling chain
 * (sampling.c), built as this one translation unit (the plant's stepping is the plant's own module,
 * plant/c/steps_module.c).
 *
 * Why: these entry points run several times per cycle of a flight controller (the IMU's block of
 * samples, its two low-pass filters, its data registers, the magnetometer's samples). Through ctypes each call cost 5-7 thousand instructions of argument conversion and libffi
 * set-up, around a few hundred of arithmetic: together about a third of the session's work per cycle.
 * Called as METH_FASTCALL functions they cost a few hundred. The set-up calls (sizes, init) stay on
 * ctypes (emulators/native.py loads this same file with ctypes.CDLL for those).
 *
 * Arguments are Python ints and floats; pointers are addresses as ints, made by the rig from its own
 * buffers (never from a DUT's bytes). Each function checks its argument count and types.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "sampling.c"

static int args_ok(const char *name, Py_ssize_t nargs, Py_ssize_t want)
{
    if (nargs == want)
        return 1;
    PyErr_Format(PyExc_TypeError, "%s takes %zd arguments (%zd given)", name, want, nargs);
    return 0;
}

static void *ptr(PyObject *o) { return PyLong_AsVoidPtr(o); }
static int32_t i32(PyObject *o) { return (int32_t)PyLong_AsLong(o); }

/* imu_measure(accel, gyro, n, times, rows, cols, die_offset, out) -> 0, or 1/2: that channel needs normals */
static PyObject *fc_imu_measure(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("imu_measure", nargs, 8))
        return NULL;
    rig_channel *accel = ptr(a[0]), *gyro = ptr(a[1]);
    int32_t n = i32(a[2]);
    const double *t = ptr(a[3]);
    const double *const *rows = ptr(a[4]);
    const int32_t *cols = ptr(a[5]);
    double die_offset = PyFloat_AsDouble(a[6]);
    double *out = ptr(a[7]);
    if (PyErr_Occurred())
        return NULL;
    return PyLong_FromLong(rig_imu_measure(accel, gyro, n, t, rows, cols, die_offset, out));
}

/* lowpass_run(state, n, xs, stride, a, depth) */
static PyObject *fc_lowpass_run(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("lowpass_run", nargs, 6))
        return NULL;
    rig_lowpass *f = ptr(a[0]);
    int32_t n = i32(a[1]);
    double *xs = ptr(a[2]);
    int32_t stride = i32(a[3]);
    double gain = PyFloat_AsDouble(a[4]);
    int32_t depth = i32(a[5]);
    if (PyErr_Occurred())
        return NULL;
    rig_lowpass_run(f, n, xs, stride, gain, depth);
    Py_RETURN_NONE;
}

/* mpu_encode(row, regs, accel_lsb, gyro_lsb, accel_self_test, gyro_self_test, standby, temp_disabled,
 *            st, g0): rig_mpu_encode with its two pairs passed as values */
static PyObject *fc_mpu_encode(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("mpu_encode", nargs, 10))
        return NULL;
    const double *row = ptr(a[0]);
    uint8_t *regs = ptr(a[1]);
    double lsb[2] = { PyFloat_AsDouble(a[2]), PyFloat_AsDouble(a[3]) };
    int32_t self_test[2] = { i32(a[4]), i32(a[5]) };
    int32_t standby = i32(a[6]), temp_disabled = i32(a[7]);
    const double *st = ptr(a[8]);
    double g0 = PyFloat_AsDouble(a[9]);
    if (PyErr_Occurred())
        return NULL;
    rig_mpu_encode(row, regs, lsb, self_test, standby, temp_disabled, st, g0);
    Py_RETURN_NONE;
}

/* channel_measure(channel, n, t, truth, temperature, out) -> 0, or 1: it needs normals */
static PyObject *fc_channel_measure(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("channel_measure", nargs, 6))
        return NULL;
    rig_channel *c = ptr(a[0]);
    int32_t n = i32(a[1]);
    const double *t = ptr(a[2]), *truth = ptr(a[3]), *temperature = ptr(a[4]);
    double *out = ptr(a[5]);
    if (PyErr_Occurred())
        return NULL;
    return PyLong_FromLong(rig_channel_measure(c, n, t, truth, temperature, out));
}

static PyMethodDef methods[] = {
    { "imu_measure", (PyCFunction)(void (*)(void))fc_imu_measure, METH_FASTCALL, "rig_imu_measure" },
    { "lowpass_run", (PyCFunction)(void (*)(void))fc_lowpass_run, METH_FASTCALL, "rig_lowpass_run" },
    { "mpu_encode", (PyCFunction)(void (*)(void))fc_mpu_encode, METH_FASTCALL, "rig_mpu_encode" },
    { "channel_measure", (PyCFunction)(void (*)(void))fc_channel_measure, METH_FASTCALL, "rig_channel_measure" },
    { NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT,
    "_rignative",
    "The rig's C library: its per-cycle entry points.",
    -1,
    methods,
    NULL,
    NULL,
    NULL,
    NULL,
};

PyMODINIT_FUNC PyInit__rignative(void) { return PyModule_Create(&module); }
