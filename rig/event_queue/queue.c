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

/* a before b */
static inline int earlier(const event_entry *a, const event_entry *b)
{
    return a->t_ns < b->t_ns || (a->t_ns == b->t_ns && a->seq < b->seq);
}

static void sift_up(event_entry *h, Py_ssize_t i)
{
    event_entry e = h[i];
    while (i > 0) {
        Py_ssize_t parent = (i - 1) / 2;
        if (!earlier(&e, &h[parent]))
            break;
        h[i] = h[parent];
        i = parent;
    }
    h[i] = e;
}

static void sift_down(event_entry *h, Py_ssize_t n, Py_ssize_t i)
{
    event_entry e = h[i];
    for (;;) {
        Py_ssize_t c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && earlier(&h[c + 1], &h[c]))
            c++;
        if (!earlier(&h[c], &e))
            break;
        h[i] = h[c];
        i = c;
    }
    h[i] = e;
}

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
        Py_VISIT(q->heap[i].fn);
    return 0;
}

static int eq_clear(event_queue *q)
{
    while (q->n > 0) { /* (one at a time: a function's release may run code that looks at the queue) */
        PyObject *fn = q->heap[--q->n].fn;
        Py_DECREF(fn);
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

/* push(t_ns, fn): schedules fn at t_ns (an int; one past the 64-bit range is kept at its end) */
static PyObject *eq_push(event_queue *q, PyObject *const *a, Py_ssize_t nargs)
{
    if (nargs != 2 || !PyLong_Check(a[0]))
        return PyErr_Format(PyExc_TypeError, "push takes a time (int, ns) and a function");
    int overflow = 0;
    long long t = PyLong_AsLongLongAndOverflow(a[0], &overflow);
    if (t == -1 && PyErr_Occurred())
        return NULL;
    if (overflow)
        t = overflow > 0 ? INT64_MAX : INT64_MIN;
    if (q->n == q->cap) {
        Py_ssize_t cap = q->cap ? 2 * q->cap : 16;
        event_entry *h = PyMem_Realloc(q->heap, (size_t)cap * sizeof *h);
        if (!h)
            return PyErr_NoMemory();
        q->heap = h;
        q->cap = cap;
    }
    q->heap[q->n] = (event_entry){ .t_ns = t, .seq = q->next_seq++, .fn = Py_NewRef(a[1]) };
    sift_up(q->heap, q->n++);
    Py_RETURN_NONE;
}

/* pop() -> (t_ns, fn): the first event, taken off; IndexError when there is none */
static PyObject *eq_pop(event_queue *q, PyObject *unused)
{
    (void)unused;
    if (q->n == 0) {
        PyErr_SetString(PyExc_IndexError, "pop from an empty event queue");
        return NULL;
    }
    PyObject *t = PyLong_FromLongLong(q->heap[0].t_ns);
    PyObject *out = t ? PyTuple_New(2) : NULL;
    if (!out) {
        Py_XDECREF(t);
        return NULL;
    }
    PyTuple_SET_ITEM(out, 0, t);
    PyTuple_SET_ITEM(out, 1, q->heap[0].fn); /* (the queue's reference, now the tuple's) */
    if (--q->n > 0) {
        q->heap[0] = q->heap[q->n];
        sift_down(q->heap, q->n, 0);
    }
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
    if (PyType_Ready(&EventQueueType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m && PyModule_AddObjectRef(m, "EventQueue", (PyObject *)&EventQueueType) < 0)
        Py_CLEAR(m);
    return m;
}
