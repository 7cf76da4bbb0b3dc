/* The Python attributes the fast path reads and writes (the PWM channels' settings, the magnetometer's
 * and barometer's producers' state, the IMU producer's after its Python serve ran, ...), through their
 * type's getset descriptor. (What both sides touch every cycle, the world's step count, the IMU's next
 * sample time and the PWM duties, are cells read in place: no attribute at all.)
 *
 * Why: PyObject_GetAttr on a mypyc-compiled object walks the type's MRO for the name, finds the getset
 * descriptor mypyc made for the attribute, checks it and calls its getter: about 200 instructions, 21
 * times per FC cycle (4 k of a flight's 63 k). The getter itself is a few dozen. So the descriptor's
 * getter and setter are found once per (type, name) and kept in a small cache, valid while the type's
 * version tag is the one seen (CPython gives a type a new tag whenever it is changed; a type without a
 * valid tag is never cached). Anything else (a plain Python object, whose attributes live in its
 * __dict__ when mypyc is off; a type with its own __getattr__) takes PyObject_GetAttr, as before: the
 * result is the same either way, only the route differs. */

#define ATTR_CACHE_BITS 9 /* 512 entries for the few dozen (type, name) pairs a session meets: with 64, a few */
#define ATTR_CACHE (1 << ATTR_CACHE_BITS) /* hot pairs evicted each other every cycle (~130 instructions) */

typedef struct {
    PyTypeObject *type; /* (both held: neither's address can be another's while it is here) */
    PyObject *name;
    unsigned int version;
    PyGetSetDef *gs; /* NULL: the generic route */
} attr_entry;

static attr_entry attr_cache[ATTR_CACHE];

/* the getset of o's type for name, or NULL: the generic route */
static PyGetSetDef *getset_of(PyObject *o, PyObject *name)
{
    PyTypeObject *t = Py_TYPE(o);
    uint64_t key = ((uint64_t)(uintptr_t)t >> 4) ^ ((uint64_t)(uintptr_t)name >> 4);
    attr_entry *e = &attr_cache[(key * 0x9E3779B97F4A7C15u) >> (64 - ATTR_CACHE_BITS)]; /* (Fibonacci hashing) */
    int valid = PyType_HasFeature(t, Py_TPFLAGS_VALID_VERSION_TAG);
    if (valid && e->type == t && e->name == name && e->version == t->tp_version_tag)
        return e->gs;
    PyObject *d = _PyType_Lookup(t, name); /* (borrowed; gives the type a version tag) */
    PyGetSetDef *gs = d && Py_IS_TYPE(d, &PyGetSetDescr_Type) && t->tp_getattro == PyObject_GenericGetAttr &&
                              t->tp_setattro == PyObject_GenericSetAttr
                          ? ((PyGetSetDescrObject *)d)->d_getset
                          : NULL;
    if (PyType_HasFeature(t, Py_TPFLAGS_VALID_VERSION_TAG)) {
        Py_INCREF(t);
        Py_INCREF(name);
        Py_XDECREF(e->type);
        Py_XDECREF(e->name);
        e->type = t;
        e->name = name;
        e->version = t->tp_version_tag;
        e->gs = gs;
    }
    return gs;
}

/* o.name: a new reference, or NULL (raised) */
static PyObject *attr_get(PyObject *o, PyObject *name)
{
    PyGetSetDef *gs = getset_of(o, name);
    return gs && gs->get ? gs->get(o, gs->closure) : PyObject_GetAttr(o, name);
}

/* o.name = v: 0, or -1 (raised) */
static int attr_set(PyObject *o, PyObject *name, PyObject *v)
{
    PyGetSetDef *gs = getset_of(o, name);
    return gs && gs->set ? gs->set(o, v, gs->closure) : PyObject_SetAttr(o, name, v);
}

static int attr_ll(PyObject *o, PyObject *name, long long *out)
{
    PyObject *v = attr_get(o, name);
    if (!v)
        return -1;
    *out = PyLong_AsLongLong(v);
    Py_DECREF(v);
    return *out == -1 && PyErr_Occurred() ? -1 : 0;
}

static int attr_double(PyObject *o, PyObject *name, double *out)
{
    PyObject *v = attr_get(o, name);
    if (!v)
        return -1;
    *out = PyFloat_AsDouble(v);
    Py_DECREF(v);
    return *out == -1.0 && PyErr_Occurred() ? -1 : 0;
}

/* o.<name> as an address (a cell's or a C state's address attribute), read by name at set-up: the
 * address, or NULL (raised, or the attribute is 0) */
static void *address_attr(PyObject *o, const char *name)
{
    PyObject *v = PyObject_GetAttrString(o, name);
    void *p = v ? PyLong_AsVoidPtr(v) : NULL;
    Py_XDECREF(v);
    return p;
}

/* attribute `name` of o is true: 1, false: 0, -1: error */
static int attr_true(PyObject *o, PyObject *name)
{
    PyObject *v = attr_get(o, name);
    int r = v ? PyObject_IsTrue(v) : -1;
    Py_XDECREF(v);
    return r;
}

/* 1: o.name is still `expected` (a producer's model or the model's disturbance, replaced after setup:
 * then the Python producer serves); 0: it is another object; -1: error */
static int same_attr(PyObject *o, PyObject *name, PyObject *expected)
{
    PyObject *v = attr_get(o, name);
    if (!v)
        return -1;
    Py_DECREF(v);
    return v == expected;
}

/* attr(o, name) -> o.name by this route: the tests' view of it */
static PyObject *fp_attr(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 2 || !PyUnicode_Check(a[1]))
        return PyErr_Format(PyExc_TypeError, "attr takes an object and a name");
    return attr_get(a[0], a[1]);
}
