/* The scheduled events a lockstep wait crosses, run from the fast path (included by fastpath.c).
 *
 * Why: the recorder and the wind tick at 100 Hz and the sticks' SBUS frames at about 70 Hz, so about
 * every other FC cycle's wait crosses an event. Declined to the Python handler, such a wait cost about
 * 28 k instructions more than the event's own work (parsed, dispatched, the world stepped and the reply
 * built in Python): a fifth of a whole flight's cost per FC cycle (bench/run_instructions.py).
 *
 * How: a wait the fast path takes runs the events due before its time as Scheduler.advance does, one
 * Scheduler.run_next each (the same Python step, so an event runs alike on both paths), the world stepped
 * to each event's time here first, in C, so that run_next's own step finds nothing left to do. A polling
 * wait ends at the first event that wrote to the DUT, as Scheduler.advance(stop_on_output) ends it. What
 * the events wrote to the DUT's ports is handed over (as Session.deliver_serial does) before the DUT runs again.
 * A wait with an event due is taken only once it is checked completely: once an event has run, the wait
 * is the fast path's to finish, and nothing is left for the handler to do again.
 */
#include <sched.h>
#include <sys/ioctl.h>
#include <time.h>

static PyObject *s_event_output;

/* The scheduler's first event's time (0 for one at or before 0): 1, or 0 when there is none. clear_until
 * (fastpath.c) and run_due read it ~8 times a cycle, from the queue's struct (rig/event_queue/queue.h) */
static int first_event_ns(fast_state *s, uint64_t *t)
{
    if (s->events->n == 0)
        return 0;
    int64_t first = s->events->heap[0].t_ns;
    *t = first <= 0 ? 0 : (uint64_t)first;
    return 1;
}

/* Scheduler.advance's events up to t (the world is not moved to t itself). With stop_on_output, the
 * first event that wrote to the DUT ends it: *woke is its time. 1: done; -1: error (an event's Stop) */
static int run_due(fast_state *s, uint64_t t, int stop_on_output, uint64_t *woke)
{
    *woke = t;
    uint64_t first;
    while (first_event_ns(s, &first) && first <= t) {
        if (first > 0 && world_to(s, first) < 0)
            return -1;
        PyObject *te = PyObject_CallNoArgs(s->run_next);
        if (!te)
            return -1;
        unsigned long long when = PyLong_AsUnsignedLongLong(te);
        Py_DECREF(te);
        if (when == (unsigned long long)-1 && PyErr_Occurred())
            return -1;
        if (stop_on_output) {
            PyObject *out = attr_get(s->sched, s_event_output);
            int wrote = out ? PyObject_IsTrue(out) : -1;
            Py_XDECREF(out);
            if (wrote < 0)
                return -1;
            if (wrote) {
                *woke = when;
                return 1;
            }
        }
    }
    return 1;
}

/* the wall clock for a wait's deadline (here and pump.c's budget) */
static uint64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * NS + (uint64_t)ts.tv_nsec;
}

/* the bytes readable on fd (FIONREAD): >= 0, or -1 (errno set) */
static int readable_on(int fd)
{
    int n = 0;
    return ioctl(fd, FIONREAD, &n) < 0 ? -1 : n;
}

/* pending_input(fd) -> the bytes readable on fd: Session.serial_write's count of what the DUT has not
 * read yet (~70 times a second; through fcntl and array it was 4 k instructions a call) */
static PyObject *fp_pending_input(PyObject *self, PyObject *arg)
{
    (void)self;
    long fd = PyLong_AsLong(arg);
    if (fd == -1 && PyErr_Occurred())
        return NULL;
    int n = fd < 0 || fd > INT32_MAX ? (errno = EBADF, -1) : readable_on((int)fd);
    return n < 0 ? PyErr_SetFromErrno(PyExc_OSError) : PyLong_FromLong(n);
}

/* Session.deliver_serial, when the events wrote to the DUT's ports: each pty's bytes readable on the
 * DUT's side (a count the kernel's worker reaches soon after the write) before it runs again, waited
 * for here rather than in Python (a frame's wait was 7 k instructions there: FIONREAD by fcntl) */
static int deliver_written(fast_state *s)
{
    if (!s->in_flight || PyDict_GET_SIZE(s->in_flight) == 0)
        return 0;
    uint64_t deadline = mono_ns() + NS;
    Py_ssize_t pos = 0;
    PyObject *key, *value;
    while (PyDict_Next(s->in_flight, &pos, &key, &value)) {
        int fd = (int)PyLong_AsLong(key);
        long target = PyLong_AsLong(value);
        if (PyErr_Occurred())
            return -1;
        for (;;) {
            int readable = readable_on(fd);
            if (readable < 0) {
                PyErr_SetFromErrno(PyExc_OSError);
                return -1;
            }
            if (readable >= target || mono_ns() >= deadline)
                break;
            sched_yield();
        }
    }
    PyDict_Clear(s->in_flight);
    return 0;
}

/* setup_events(state, run_next, in_flight): the events a wait crosses run here from now on; in_flight is
 * Session.in_flight, what they wrote to the DUT's ptys (slave fd -> bytes readable once delivered) */
static PyObject *fp_setup_events(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 3)
        return PyErr_Format(PyExc_TypeError, "setup_events takes 3 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    if (!s)
        return NULL;
    if (!PyCallable_Check(a[1]) || !PyDict_Check(a[2]))
        return PyErr_Format(PyExc_TypeError, "setup_events: run_next and a dict");
    if (!s_event_output && !(s_event_output = PyUnicode_InternFromString("event_output")))
        return NULL;
    PyObject **refs[] = { &s->run_next, &s->in_flight };
    for (int i = 0; i < 2; i++) {
        Py_INCREF(a[i + 1]);
        Py_XSETREF(*refs[i], a[i + 1]);
    }
    Py_RETURN_NONE;
}
