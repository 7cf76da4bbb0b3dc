/* The scheduled events' queue (rig/event_queue): its layout, shared by the module that makes it
 * (queue.c) and the lockstep fast path that reads its first event (rig/lockstep/events.c).
 *
 * A binary min-heap of (time, sequence number, function): events run in order of time, ties in the
 * order they were scheduled. Times are sim time in ns as signed 64-bit integers (a time past them is
 * kept at the end of the range: 292 years, never reached). */
#ifndef RIG_EVENT_QUEUE_H
#define RIG_EVENT_QUEUE_H

#include <Python.h>
#include <stdint.h>

/* the type's name and a layout mark: the fast path reads a queue only when both are these */
#define EVENT_QUEUE_TYPE_NAME "_rigevents.EventQueue"
#define EVENT_QUEUE_MAGIC 0x45565131u /* "EVQ1" */

typedef struct {
    int64_t t_ns;
    uint64_t seq;
    PyObject *fn; /* held */
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

#endif
