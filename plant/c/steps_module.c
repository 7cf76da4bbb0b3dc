/* The plant's stepping (plant_steps.c) as a CPython extension module, ``_plantsteps``: the world steps
 * the plant between every two requests of a DUT, so the call is made as a METH_FASTCALL function, a
 * few hundred instructions, where ctypes cost thousands (plant/steps.py builds and loads it).
 *
 * The arguments are Python ints and floats; the pointer is an address as an int, made by plant/fmu.py
 * from its own struct (never from a DUT's bytes). The argument count and types are checked.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "plant_steps.c"

/* plant_steps(steps, n, h, write_inputs, first_row) -> steps completed */
static PyObject *plant_steps(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 5) {
        PyErr_Format(PyExc_TypeError, "plant_steps takes 5 arguments (%zd given)", nargs);
        return NULL;
    }
    struct rig_plant_steps *s = PyLong_AsVoidPtr(a[0]);
    int32_t n = (int32_t)PyLong_AsLong(a[1]);
    double h = PyFloat_AsDouble(a[2]);
    int32_t write_inputs = (int32_t)PyLong_AsLong(a[3]);
    int64_t first_row = PyLong_AsLongLong(a[4]);
    if (PyErr_Occurred())
        return NULL;
    return PyLong_FromLong(rig_plant_steps(s, n, h, write_inputs, first_row));
}

typedef int (*get_boolean_fn)(void *c, const unsigned int vr[], size_t nvr, int value[]);

/* get_boolean(fmi2GetBoolean_address, component, vr) -> the value (0 or 1), or minus the status when
 * the call returned Discard or worse: one Boolean the recorder reads at 100 Hz (the plant's on_ground),
 * where a ctypes call cost about 10 k instructions */
static PyObject *get_boolean(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 3) {
        PyErr_Format(PyExc_TypeError, "get_boolean takes 3 arguments (%zd given)", nargs);
        return NULL;
    }
    get_boolean_fn fn = (get_boolean_fn)PyLong_AsVoidPtr(a[0]);
    void *component = PyLong_AsVoidPtr(a[1]);
    unsigned int vr = (unsigned int)PyLong_AsUnsignedLong(a[2]);
    if (PyErr_Occurred())
        return NULL;
    if (!fn || !component) {
        PyErr_SetString(PyExc_ValueError, "get_boolean: a function and a component");
        return NULL;
    }
    int value = 0, status = fn(component, &vr, 1, &value);
    return PyLong_FromLong(status > 1 ? -status : value != 0);
}

/* the doubles at a tuple's indices of an array of n, into out[]: 0, or -1 (raised) */
static int gather_into(double *out, const double *v, Py_ssize_t n, PyObject *idx)
{
    for (Py_ssize_t i = 0; i < PyTuple_GET_SIZE(idx); i++) {
        Py_ssize_t k = PyLong_AsSsize_t(PyTuple_GET_ITEM(idx, i));
        if (k == -1 && PyErr_Occurred())
            return -1;
        if (k < 0 || k >= n) {
            PyErr_Format(PyExc_IndexError, "gather: index %zd outside %zd values", k, n);
            return -1;
        }
        out[i] = v[k];
    }
    return 0;
}

/* gather(a_address, a_len, a_indices, b_address, b_len, b_indices, out_address, out_room, extras) ->
 * None: some of the plant's outputs and inputs, then the floats of the tuple extras, written to the
 * doubles at out_address (a row of the recorder's table at 100 Hz: where numpy indexing, lists of
 * floats and a table made of tuples after the run cost about 15 k instructions a row). The addresses
 * are the plant's own buffers (plant/fmu.py) and the caller's table (rig/world.py's Probe, which says
 * how many doubles are left from out_address: out_room); each index is checked against its buffer's
 * length, and the row against the room. */
static PyObject *gather(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 9) {
        PyErr_Format(PyExc_TypeError, "gather takes 9 arguments (%zd given)", nargs);
        return NULL;
    }
    if (!PyTuple_Check(a[2]) || !PyTuple_Check(a[5]) || !PyTuple_Check(a[8])) {
        PyErr_SetString(PyExc_TypeError, "gather: the indices and the extras are tuples");
        return NULL;
    }
    const double *va = PyLong_AsVoidPtr(a[0]), *vb = PyLong_AsVoidPtr(a[3]);
    double *out = PyLong_AsVoidPtr(a[6]);
    Py_ssize_t na = PyLong_AsSsize_t(a[1]), nb = PyLong_AsSsize_t(a[4]), room = PyLong_AsSsize_t(a[7]);
    if (PyErr_Occurred())
        return NULL;
    if (!va || !vb || !out) {
        PyErr_SetString(PyExc_ValueError, "gather: three buffers' addresses");
        return NULL;
    }
    Py_ssize_t from_a = PyTuple_GET_SIZE(a[2]), from_b = PyTuple_GET_SIZE(a[5]), extras = PyTuple_GET_SIZE(a[8]);
    if (from_a + from_b + extras > room) {
        PyErr_Format(PyExc_IndexError, "gather: a row of %zd values where %zd are left", from_a + from_b + extras,
                     room);
        return NULL;
    }
    if (gather_into(out, va, na, a[2]) < 0 || gather_into(out + from_a, vb, nb, a[5]) < 0)
        return NULL;
    for (Py_ssize_t i = 0; i < extras; i++) {
        double x = PyFloat_AsDouble(PyTuple_GET_ITEM(a[8], i));
        if (x == -1.0 && PyErr_Occurred())
            return NULL;
        out[from_a + from_b + i] = x;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    { "plant_steps", (PyCFunction)(void (*)(void))plant_steps, METH_FASTCALL, "rig_plant_steps" },
    { "get_boolean", (PyCFunction)(void (*)(void))get_boolean, METH_FASTCALL, "one fmi2GetBoolean" },
    { "gather", (PyCFunction)(void (*)(void))gather, METH_FASTCALL, "some outputs and inputs into a row" },
    { NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_plantsteps", "Several plant steps in one call.", -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__plantsteps(void) { return PyModule_Create(&module); }
