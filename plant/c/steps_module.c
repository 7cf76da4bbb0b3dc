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

static PyMethodDef methods[] = {
    { "plant_steps", (PyCFunction)(void (*)(void))plant_steps, METH_FASTCALL, "rig_plant_steps" },
    { NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_plantsteps", "Several plant steps in one call.", -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__plantsteps(void) { return PyModule_Create(&module); }
