/* The scheduled events' queue (rig/event_queue): its layout, shared by the module that makes it
 * (queue.c) and the lockstep fast path that reads its first event and takes the stores off it
 * (rig/lockstep/events.c).
 *
 * A binary min-heap of (time, sequence number, function): events run in order of time, ties in the
 * order they were scheduled. Times are sim time in ns as signed 64-bit integers (a time past them is
 * kept at the end of the range: 292 years, never reached). A store is an event without a function: a
 * value written into a double (a plant input's cell) at its time, which the fast path does without
 * calling into Python. */
#ifndef RIG_EVENT_QUEUE_H
#define RIG_EVENT_QUEUE_H

#include <Python.h>
#include <stdint.h>

/* the type's name and a layout mark: the fast path reads a queue only when both are these */
#define EVENT_QUEUE_TYPE_NAME "_rigevents.EventQueue"
#define EVENT_QUEUE_MAGIC 0x45565132u /* "EVQ2": an entry holds a store too */

typedef struct {
    int64_t t_ns;
    uint64_t seq;
    PyObject *fn; /* held; NULL: a store */
    double *cell; /* a store: where it writes value */
    double value;
} event_entry;

typedef struct {
    PyObject_HEAD uint32_t magic;
    Py_ssize_t n, cap;
    uint64_t next_seq;
    event_entry *heap;
} event_queue;

/* q is a queue of this layout (checked by name, size and mark: it comes from another extension) */
static inline int event_queue_check(PyObject *q)
{
    PyTypeObject *t = Py_TYPE(q);
    return t->tp_basicsize == (Py_ssize_t)sizeof(event_queue) && strcmp(t->tp_name, EVENT_QUEUE_TYPE_NAME) == 0 &&
           ((event_queue *)q)->magic == EVENT_QUEUE_MAGIC;
}

/* a before b */
static inline int event_earlier(const event_entry *a, const event_entry *b)
{
    return a->t_ns < b->t_ns || (a->t_ns == b->t_ns && a->seq < b->seq);
}

static inline void event_sift_down(event_entry *h, Py_ssize_t n, Py_ssize_t i)
{
    event_entry e = h[i];
    for (;;) {
        Py_ssize_t c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && event_earlier(&h[c + 1], &h[c]))
            c++;
        if (!event_earlier(&h[c], &e))
            break;
        h[i] = h[c];
        i = c;
    }
    h[i] = e;
}

/* The first event taken off a queue that has one (its reference to fn, if any, is the caller's now) */
static inline event_entry event_take_first(event_queue *q)
{
    event_entry first = q->heap[0];
    if (--q->n > 0) {
        q->heap[0] = q->heap[q->n];
        event_sift_down(q->heap, q->n, 0);
    }
    return first;
}

#endif
