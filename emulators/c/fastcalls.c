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
 * The chip core (emulators/chips/, compiled into this same library) has its per-transfer entry points
 * here too: chip_transfer, chip_advance and chip_push_*; its set-up calls are ctypes' (native.chips()).
 *
 * Arguments are Python ints and floats; pointers are addresses as ints, made by the rig from its own
 * buffers (never from a DUT's bytes). Each function checks its argument count and types.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "sampling.c"

#include "chip_core.h"

static int args_ok(const char *name, Py_ssize_t nargs, Py_ssize_t want)
{
    if (nargs == want)
        return 1;
    PyErr_Format(PyExc_TypeError, "%s takes %zd arguments (%zd given)", name, want, nargs);
    return 0;
}

static void *ptr(PyObject *o) { return PyLong_AsVoidPtr(o); }
static int32_t i32(PyObject *o) { return (int32_t)PyLong_AsLong(o); }

/* imu_measure(accel, gyro, times, rows, cols, die_offset, out) -> 0, or 1/2: that channel needs normals.
 * times: the sample instants (floats, at most IMU_BLOCK_MAX), rows: the address of each one's truth row (ints) */
#define IMU_BLOCK_MAX 64 /* emulators.native.BLOCK */
static PyObject *fc_imu_measure(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("imu_measure", nargs, 7))
        return NULL;
    rig_channel *accel = ptr(a[0]), *gyro = ptr(a[1]);
    const int32_t *cols = ptr(a[4]);
    double die_offset = PyFloat_AsDouble(a[5]);
    double *out = ptr(a[6]);
    if (PyErr_Occurred())
        return NULL;
    PyObject *ts = PySequence_Fast(a[2], "imu_measure takes a sequence of times");
    if (!ts)
        return NULL;
    PyObject *rs = PySequence_Fast(a[3], "imu_measure takes a sequence of row addresses");
    if (!rs) {
        Py_DECREF(ts);
        return NULL;
    }
    PyObject *result = NULL;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(ts);
    double t[IMU_BLOCK_MAX];
    const double *rows[IMU_BLOCK_MAX];
    if (n > IMU_BLOCK_MAX || PySequence_Fast_GET_SIZE(rs) != n) {
        PyErr_Format(PyExc_ValueError, "imu_measure takes as many rows as times, at most %d", IMU_BLOCK_MAX);
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        t[i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(ts, i));
        rows[i] = ptr(PySequence_Fast_GET_ITEM(rs, i));
        if (PyErr_Occurred())
            goto done;
    }
    result = PyLong_FromLong(rig_imu_measure(accel, gyro, (int32_t)n, t, rows, cols, die_offset, out));
done:
    Py_DECREF(ts);
    Py_DECREF(rs);
    return result;
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

/* mpu_encode(row, regs): chip_mpu_encode, the chip core's encoder (regs: the MPU register image) */
static PyObject *fc_mpu_encode(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("mpu_encode", nargs, 2))
        return NULL;
    const double *row = ptr(a[0]);
    uint8_t *regs = ptr(a[1]);
    if (PyErr_Occurred())
        return NULL;
    chip_mpu_encode(regs, row);
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

/* ---- the chip core (emulators/chips/chip_core.h) ---- */

EXPORT size_t rig_chip_board_size(void) { return sizeof(chip_board); }

static uint64_t u64(PyObject *o) { return (uint64_t)PyLong_AsUnsignedLongLong(o); }

#include "need_tuple.h"

#define MAX_MSGS 42 /* I2C_RDWR_IOCTL_MAX_MSGS */

static PyObject *s_addr, *s_read, *s_data, *s_length, *s_recv_len;

/* chip_transfer(board, t_ns, msgs) -> (CHIP_OK, [bytes of each read]) | (CHIP_NACK, index) |
 * (CHIP_PROTOCOL, (index, count)) | (CHIP_NEED, need): msgs are emulators.i2c_bus.Msg */
static PyObject *fc_chip_transfer(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("chip_transfer", nargs, 3))
        return NULL;
    chip_board *b = ptr(a[0]);
    uint64_t t = u64(a[1]);
    if (PyErr_Occurred())
        return NULL;
    PyObject *seq = PySequence_Fast(a[2], "chip_transfer takes a sequence of messages");
    if (!seq)
        return NULL;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(seq);
    if (n > MAX_MSGS) {
        Py_DECREF(seq);
        return PyErr_Format(PyExc_ValueError, "chip_transfer takes at most %d messages", MAX_MSGS);
    }
    chip_msg msgs[MAX_MSGS];
    PyObject *reads[MAX_MSGS] = { 0 };
    PyObject *keep[MAX_MSGS] = { 0 }; /* the write messages' data, alive while C reads it */
    PyObject *result = NULL;
    Py_ssize_t i;
    for (i = 0; i < n; i++) {
        PyObject *m = PySequence_Fast_GET_ITEM(seq, i);
        PyObject *addr = PyObject_GetAttr(m, s_addr), *rd = PyObject_GetAttr(m, s_read);
        if (!addr || !rd) {
            Py_XDECREF(addr);
            Py_XDECREF(rd);
            goto done;
        }
        long ad = PyLong_AsLong(addr);
        int is_read = PyObject_IsTrue(rd);
        Py_DECREF(addr);
        Py_DECREF(rd);
        if (PyErr_Occurred())
            goto done;
        msgs[i].addr = (uint8_t)ad;
        if (is_read) {
            PyObject *rl = PyObject_GetAttr(m, s_recv_len);
            PyObject *len = PyObject_GetAttr(m, s_length);
            if (!rl || !len) {
                Py_XDECREF(rl);
                Py_XDECREF(len);
                goto done;
            }
            int recv_len = PyObject_IsTrue(rl);
            long ln = PyLong_AsLong(len);
            Py_DECREF(rl);
            Py_DECREF(len);
            if (PyErr_Occurred())
                goto done;
            if (ln < 0 || ln > 0xFFFF) {
                PyErr_SetString(PyExc_ValueError, "a read message's length is 0..65535");
                goto done;
            }
            Py_ssize_t size = recv_len ? 1 + CHIP_SMBUS_BLOCK_MAX : ln;
            reads[i] = PyBytes_FromStringAndSize(NULL, size);
            if (!reads[i])
                goto done;
            msgs[i].flags = (uint8_t)(CHIP_MSG_READ | (recv_len ? CHIP_MSG_RECV_LEN : 0));
            msgs[i].len = (uint16_t)size;
            msgs[i].buf = (uint8_t *)PyBytes_AS_STRING(reads[i]);
        } else {
            keep[i] = PyObject_GetAttr(m, s_data);
            if (!keep[i])
                goto done;
            char *data;
            Py_ssize_t len;
            if (PyBytes_AsStringAndSize(keep[i], &data, &len) < 0)
                goto done;
            if (len > 0xFFFF) {
                PyErr_SetString(PyExc_ValueError, "a write message carries at most 65535 bytes");
                goto done;
            }
            msgs[i].flags = 0;
            msgs[i].len = (uint16_t)len;
            msgs[i].buf = (uint8_t *)data;
        }
    }
    chip_need need;
    uint32_t failed = 0;
    int status = chip_transfer(b, t, msgs, (uint32_t)n, &need, &failed);
    if (status == CHIP_OK) {
        Py_ssize_t k = 0;
        for (i = 0; i < n; i++)
            k += reads[i] != NULL;
        PyObject *list = PyList_New(k);
        if (!list)
            goto done;
        k = 0;
        for (i = 0; i < n; i++) {
            if (!reads[i])
                continue;
            if (msgs[i].flags & CHIP_MSG_RECV_LEN && _PyBytes_Resize(&reads[i], msgs[i].len) < 0) {
                Py_DECREF(list);
                goto done;
            }
            PyList_SET_ITEM(list, k++, reads[i]);
            reads[i] = NULL;
        }
        result = Py_BuildValue("(iN)", status, list);
    } else if (status == CHIP_NEED) {
        result = Py_BuildValue("(iN)", status, need_tuple(&need));
    } else if (status == CHIP_NACK) {
        result = Py_BuildValue("(iI)", status, failed);
    } else {
        result = Py_BuildValue("(i(Ii))", status, failed, msgs[failed].buf[0]);
    }
done:
    for (i = 0; i < n; i++) {
        Py_XDECREF(reads[i]);
        Py_XDECREF(keep[i]);
    }
    Py_DECREF(seq);
    return result;
}

/* chip_advance(board, now_ns) -> None (caught up) or the need tuple */
static PyObject *fc_chip_advance(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("chip_advance", nargs, 2))
        return NULL;
    chip_board *b = ptr(a[0]);
    uint64_t t = u64(a[1]);
    if (PyErr_Occurred())
        return NULL;
    chip_need need = chip_advance(b, t);
    if (need.chip == CHIP_NONE)
        Py_RETURN_NONE;
    return need_tuple(&need);
}

/* chip_push_imu(board, first_ns, period_ns, n, rows, stride) -> samples pushed: n rows of 7 float64
 * at rows (stride float64 apart), valid at first_ns + i * period_ns */
static PyObject *fc_chip_push_imu(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("chip_push_imu", nargs, 6))
        return NULL;
    chip_board *b = ptr(a[0]);
    uint64_t first = u64(a[1]), period = u64(a[2]);
    int32_t n = i32(a[3]);
    const double *rows = ptr(a[4]);
    int32_t stride = i32(a[5]);
    if (PyErr_Occurred())
        return NULL;
    int32_t i = 0;
    while (i < n && chip_push_imu(b, first + (uint64_t)i * period, rows + (ptrdiff_t)i * stride))
        i++;
    return PyLong_FromLong(i);
}

/* chip_push_mag(board, valid_ns, x, y, z) -> pushed */
static PyObject *fc_chip_push_mag(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("chip_push_mag", nargs, 5))
        return NULL;
    chip_board *b = ptr(a[0]);
    uint64_t t = u64(a[1]);
    double f[3] = { PyFloat_AsDouble(a[2]), PyFloat_AsDouble(a[3]), PyFloat_AsDouble(a[4]) };
    if (PyErr_Occurred())
        return NULL;
    return PyBool_FromLong(chip_push_mag(b, t, f));
}

/* chip_push_baro(board, valid_ns, d1, d2) -> pushed */
static PyObject *fc_chip_push_baro(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("chip_push_baro", nargs, 4))
        return NULL;
    chip_board *b = ptr(a[0]);
    uint64_t t = u64(a[1]);
    unsigned long d1 = PyLong_AsUnsignedLong(a[2]), d2 = PyLong_AsUnsignedLong(a[3]);
    if (PyErr_Occurred())
        return NULL;
    return PyBool_FromLong(chip_push_baro(b, t, (uint32_t)d1, (uint32_t)d2));
}

/* chip_peek(board, chip, reg) -> the register as stored (no side effect; 0 outside a chip's map): the IMU
 * producer reads CONFIG and SMPLRT_DIV for every block it serves */
static PyObject *fc_chip_peek(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (!args_ok("chip_peek", nargs, 3))
        return NULL;
    const chip_board *b = ptr(a[0]);
    long chip = PyLong_AsLong(a[1]), reg = PyLong_AsLong(a[2]);
    if (PyErr_Occurred())
        return NULL;
    if (chip < 0 || chip > 0xFF || reg < 0 || reg > 0xFF)
        return PyErr_Format(PyExc_ValueError, "chip_peek: no chip %ld register %ld", chip, reg);
    return PyLong_FromLong(chip_peek(b, (uint8_t)chip, (uint8_t)reg));
}

static PyMethodDef methods[] = {
    { "imu_measure", (PyCFunction)(void (*)(void))fc_imu_measure, METH_FASTCALL, "rig_imu_measure" },
    { "lowpass_run", (PyCFunction)(void (*)(void))fc_lowpass_run, METH_FASTCALL, "rig_lowpass_run" },
    { "mpu_encode", (PyCFunction)(void (*)(void))fc_mpu_encode, METH_FASTCALL, "chip_mpu_encode" },
    { "channel_measure", (PyCFunction)(void (*)(void))fc_channel_measure, METH_FASTCALL, "rig_channel_measure" },
    { "chip_transfer", (PyCFunction)(void (*)(void))fc_chip_transfer, METH_FASTCALL, "chip_transfer" },
    { "chip_advance", (PyCFunction)(void (*)(void))fc_chip_advance, METH_FASTCALL, "chip_advance" },
    { "chip_peek", (PyCFunction)(void (*)(void))fc_chip_peek, METH_FASTCALL, "chip_peek" },
    { "chip_push_imu", (PyCFunction)(void (*)(void))fc_chip_push_imu, METH_FASTCALL, "chip_push_imu" },
    { "chip_push_mag", (PyCFunction)(void (*)(void))fc_chip_push_mag, METH_FASTCALL, "chip_push_mag" },
    { "chip_push_baro", (PyCFunction)(void (*)(void))fc_chip_push_baro, METH_FASTCALL, "chip_push_baro" },
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

PyMODINIT_FUNC PyInit__rignative(void)
{
    s_addr = PyUnicode_InternFromString("addr");
    s_read = PyUnicode_InternFromString("read");
    s_data = PyUnicode_InternFromString("data");
    s_length = PyUnicode_InternFromString("length");
    s_recv_len = PyUnicode_InternFromString("recv_len");
    if (!s_addr || !s_read || !s_data || !s_length || !s_recv_len)
        return NULL;
    return PyModule_Create(&module);
}
