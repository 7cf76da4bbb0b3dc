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

static PyMethodDef methods[] = {
    { "plant_steps", (PyCFunction)(void (*)(void))plant_steps, METH_FASTCALL, "rig_plant_steps" },
    { "get_boolean", (PyCFunction)(void (*)(void))get_boolean, METH_FASTCALL, "one fmi2GetBoolean" },
    { NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_plantsteps", "Several plant steps in one call.", -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__plantsteps(void) { return PyModule_Create(&module); }
