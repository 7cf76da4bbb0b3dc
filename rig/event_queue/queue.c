/* EventQueue: the scheduler's events (rig/scheduler.py) as a heap in C, the extension module
 * ``_rigevents``.
 *
 * Why: the recorder, the wind and the sticks' frames each schedule their next tick, so a flight pushes
 * and pops about one event per FC cycle. On heapq's list of (t_ns, seq, fn) tuples that was about 2 k
 * instructions an event (the tuple and two ints made, the tuples compared item by item in the sifts,
 * heappush and heappop looked up as globals and called generically); here a push is one method call and a
 * few dozen instructions, and the lockstep fast path reads the first event's time from the struct
 * (queue.h) instead of converting a tuple's int. The order is heapq's: by time, ties by the order of
 * scheduling.
 */
#define PY_SSIZE_T_CLEAN
#include "queue.h"

static void sift_up(event_entry *h, Py_ssize_t i)
{
    event_entry e = h[i];
    while (i > 0) {
        Py_ssize_t parent = (i - 1) / 2;
        if (!event_earlier(&e, &h[parent]))
            break;
        h[i] = h[parent];
        i = parent;
    }
    h[i] = e;
}

/* Store: a store taken off the queue from Python (Scheduler.run_next's path), a function of the host as
 * every event is: called, it writes its value into its cell */
typedef struct {
    PyObject_HEAD double *cell;
    double value;
} store_event;

static PyObject *store_call(store_event *self, PyObject *args, PyObject *kwds)
{
    (void)args, (void)kwds;
    *self->cell = self->value;
    Py_RETURN_NONE;
}

static PyTypeObject StoreType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "_rigevents.Store",
    .tp_basicsize = sizeof(store_event),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A scheduled store taken off the queue: called, it writes its value into its cell",
    .tp_call = (ternaryfunc)store_call,
};

static PyObject *eq_new(PyTypeObject *type, PyObject *args, PyObject *kwds)
{
    if (PyTuple_GET_SIZE(args) || (kwds && PyDict_GET_SIZE(kwds)))
        return PyErr_Format(PyExc_TypeError, "EventQueue() takes no arguments");
    event_queue *q = (event_queue *)type->tp_alloc(type, 0);
    if (q)
        q->magic = EVENT_QUEUE_MAGIC;
    return (PyObject *)q;
}

static int eq_traverse(event_queue *q, visitproc visit, void *arg)
{
    for (Py_ssize_t i = 0; i < q->n; i++)
        Py_VISIT(q->heap[i].fn); /* (NULL for a store: skipped) */
    return 0;
}

static int eq_clear(event_queue *q)
{
    while (q->n > 0) { /* (one at a time: a function's release may run code that looks at the queue) */
        PyObject *fn = q->heap[--q->n].fn;
        Py_XDECREF(fn);
    }
    return 0;
}

static void eq_dealloc(event_queue *q)
{
    PyObject_GC_UnTrack(q);
    eq_clear(q);
    PyMem_Free(q->heap);
    Py_TYPE(q)->tp_free((PyObject *)q);
}

/* a time argument (int, ns; one past the 64-bit range is kept at its end): 0, or -1 with the error set */
static int time_arg(PyObject *arg, long long *t)
{
    int overflow = 0;
    *t = PyLong_AsLongLongAndOverflow(arg, &overflow);
    if (*t == -1 && PyErr_Occurred())
        return -1;
    if (overflow)
        *t = overflow > 0 ? INT64_MAX : INT64_MIN;
    return 0;
}

/* e at its place in the heap, its sequence number given here: 0, or -1 (no memory) */
static int insert(event_queue *q, event_entry e)
{
    if (q->n == q->cap) {
        Py_ssize_t cap = q->cap ? 2 * q->cap : 16;
        event_entry *h = PyMem_Realloc(q->heap, (size_t)cap * sizeof *h);
        if (!h) {
            PyErr_NoMemory();
            return -1;
        }
        q->heap = h;
        q->cap = cap;
    }
    e.seq = q->next_seq++;
    q->heap[q->n] = e;
    sift_up(q->heap, q->n++);
    return 0;
}

/* push(t_ns, fn): schedules fn at t_ns */
static PyObject *eq_push(event_queue *q, PyObject *const *a, Py_ssize_t nargs)
{
    long long t;
    if (nargs != 2 || !PyLong_Check(a[0]))
        return PyErr_Format(PyExc_TypeError, "push takes a time (int, ns) and a function");
    if (time_arg(a[0], &t) < 0)
        return NULL;
    if (insert(q, (event_entry){ .t_ns = t, .fn = Py_NewRef(a[1]) }) < 0) {
        Py_DECREF(a[1]);
        return NULL;
    }
    Py_RETURN_NONE;
}

/* push_store(t_ns, address, value): value written at t_ns into the double at address (a cell the caller
 * keeps alive as long as the queue holds the store: a plant input's, World.input_address) */
static PyObject *eq_push_store(event_queue *q, PyObject *const *a, Py_ssize_t nargs)
{
    long long t;
    if (nargs != 3 || !PyLong_Check(a[0]) || !PyLong_Check(a[1]))
        return PyErr_Format(PyExc_TypeError, "push_store takes a time (int, ns), an address (int) and a value");
    if (time_arg(a[0], &t) < 0)
        return NULL;
    void *cell = PyLong_AsVoidPtr(a[1]);
    double value = PyFloat_AsDouble(a[2]);
    if (PyErr_Occurred())
        return NULL;
    if (!cell || (uintptr_t)cell % _Alignof(double))
        return PyErr_Format(PyExc_ValueError, "push_store: %zu is not the address of a double", (size_t)cell);
    if (insert(q, (event_entry){ .t_ns = t, .cell = cell, .value = value }) < 0)
        return NULL;
    Py_RETURN_NONE;
}

/* pop() -> (t_ns, fn): the first event, taken off (a store as a Store); IndexError when there is none */
static PyObject *eq_pop(event_queue *q, PyObject *unused)
{
    (void)unused;
    if (q->n == 0) {
        PyErr_SetString(PyExc_IndexError, "pop from an empty event queue");
        return NULL;
    }
    event_entry *e = &q->heap[0];
    PyObject *fn = e->fn;
    if (!fn) { /* a store: its function made now */
        store_event *st = PyObject_New(store_event, &StoreType);
        if (!st)
            return NULL;
        st->cell = e->cell, st->value = e->value;
        fn = (PyObject *)st;
    }
    PyObject *t = PyLong_FromLongLong(e->t_ns);
    PyObject *out = t ? PyTuple_New(2) : NULL;
    if (!out) {
        Py_XDECREF(t);
        if (!e->fn)
            Py_DECREF(fn);
        return NULL;
    }
    PyTuple_SET_ITEM(out, 0, t);
    PyTuple_SET_ITEM(out, 1, fn); /* (the queue's reference, or the store's new one: now the tuple's) */
    event_take_first(q);
    return out;
}

/* first_ns() -> the first event's time, or None */
static PyObject *eq_first_ns(event_queue *q, PyObject *unused)
{
    (void)unused;
    if (q->n == 0)
        Py_RETURN_NONE;
    return PyLong_FromLongLong(q->heap[0].t_ns);
}

static Py_ssize_t eq_len(event_queue *q) { return q->n; }

static PyMethodDef eq_methods[] = {
    { "push", (PyCFunction)(void (*)(void))eq_push, METH_FASTCALL,
      "push(t_ns, fn): fn scheduled at t_ns (ties run in the order pushed)" },
    { "push_store", (PyCFunction)(void (*)(void))eq_push_store, METH_FASTCALL,
      "push_store(t_ns, address, value): value written into the double at address at t_ns" },
    { "pop", (PyCFunction)eq_pop, METH_NOARGS, "pop() -> (t_ns, fn): the first event, taken off" },
    { "first_ns", (PyCFunction)eq_first_ns, METH_NOARGS, "first_ns() -> the first event's time, or None" },
    { NULL, NULL, 0, NULL },
};

static PySequenceMethods eq_as_sequence = { .sq_length = (lenfunc)eq_len };

static PyTypeObject EventQueueType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = EVENT_QUEUE_TYPE_NAME,
    .tp_basicsize = sizeof(event_queue),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC,
    .tp_doc = "The scheduled events: a heap by time, ties in the order pushed (rig/event_queue/queue.c)",
    .tp_new = eq_new,
    .tp_dealloc = (destructor)eq_dealloc,
    .tp_traverse = (traverseproc)eq_traverse,
    .tp_clear = (inquiry)eq_clear,
    .tp_methods = eq_methods,
    .tp_as_sequence = &eq_as_sequence,
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT,
    "_rigevents",
    "The scheduler's event queue (rig/event_queue)",
    -1,
    NULL,
    NULL,
    NULL,
    NULL,
    NULL,
};

PyMODINIT_FUNC PyInit__rigevents(void)
{
    if (PyType_Ready(&EventQueueType) < 0 || PyType_Ready(&StoreType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m && PyModule_AddObjectRef(m, "EventQueue", (PyObject *)&EventQueueType) < 0)
        Py_CLEAR(m);
    return m;
}
