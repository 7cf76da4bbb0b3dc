/* The real-time loop's wait, as one CPython extension module, ``_rigpace`` (rig/pace/__init__.py).
 *
 * Why C: a paced loop is late by whatever runs between "the deadline came" and "the event runs". In
 * Python the wait was a selector call with a timeout in seconds (epoll's counted in whole
 * milliseconds: every event due within the next millisecond woke up to a millisecond late), around
 * bookkeeping that a garbage collection or a page fault could stretch. Here the wait is one call: it
 * sleeps in the kernel until a little before the absolute deadline (CLOCK_MONOTONIC), still woken by
 * any of the loop's descriptors (the DUT's socket, its ptys, the bridge's link), then spins on the
 * clock (polling those descriptors without blocking) to the deadline itself. Python is entered again
 * only when the deadline has come or a descriptor is ready: to run the due event or serve the message.
 *
 * The sleep: with descriptors, ppoll(2) with a timeout computed from the absolute deadline just before
 * the call (nanoseconds, not epoll's milliseconds); without, clock_nanosleep(2) with TIMER_ABSTIME.
 * The kernel's timer slack (50 µs for a normal thread, none under SCHED_FIFO) is set by the caller
 * (timerslack()). The spin is ``spin_ns`` long at most: the part of the wait the kernel's wake-up cannot
 * be trusted with on a VM.
 *
 * Arguments are Python ints from the rig (descriptors it opened, its own deadlines), checked here.
 */
#define _GNU_SOURCE /* RUSAGE_THREAD */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <errno.h>
#include <poll.h>
#include <stdint.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <time.h>

#define MAX_FDS 64

static int64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static struct timespec to_ts(int64_t ns)
{
    struct timespec ts = { (time_t)(ns / 1000000000), (long)(ns % 1000000000) };
    return ts;
}

/* the descriptors with something to read (or hung up, or in error: the caller's read says which) */
static PyObject *ready_fds(const struct pollfd *pf, int n)
{
    PyObject *out = PyList_New(0);
    for (int i = 0; out && i < n; i++)
        if (pf[i].revents) {
            PyObject *fd = PyLong_FromLong(pf[i].fd);
            if (!fd || PyList_Append(out, fd) < 0)
                Py_CLEAR(out);
            Py_XDECREF(fd);
        }
    return out;
}

/* wait(deadline_ns, fds, spin_ns) -> [ready fds]: [] once CLOCK_MONOTONIC has reached deadline_ns (or a
 * signal came: the caller looks again), else the descriptors ready first. */
static PyObject *pace_wait(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 3) {
        PyErr_Format(PyExc_TypeError, "wait takes 3 arguments (%zd given)", nargs);
        return NULL;
    }
    int64_t deadline = PyLong_AsLongLong(a[0]);
    int64_t spin = PyLong_AsLongLong(a[2]);
    if (PyErr_Occurred())
        return NULL;
    if (!PyTuple_Check(a[1])) {
        PyErr_SetString(PyExc_TypeError, "wait: fds must be a tuple of ints");
        return NULL;
    }
    Py_ssize_t n = PyTuple_GET_SIZE(a[1]);
    if (n > MAX_FDS || spin < 0) {
        PyErr_Format(PyExc_ValueError, "wait: at most %d descriptors and a spin >= 0", MAX_FDS);
        return NULL;
    }
    struct pollfd pf[MAX_FDS];
    for (Py_ssize_t i = 0; i < n; i++) {
        long fd = PyLong_AsLong(PyTuple_GET_ITEM(a[1], i));
        if (fd == -1 && PyErr_Occurred())
            return NULL;
        if (fd < 0 || fd > INT32_MAX) {
            PyErr_Format(PyExc_ValueError, "wait: bad descriptor %ld", fd);
            return NULL;
        }
        pf[i] = (struct pollfd){ (int)fd, POLLIN, 0 };
    }
    int nfds = (int)n, r = 0, interrupted = 0;
    int64_t wake = deadline - spin;
    Py_BEGIN_ALLOW_THREADS;
    for (;;) { /* the sleep: to ``spin`` before the deadline */
        int64_t now = mono_ns();
        if (now >= wake)
            break;
        if (nfds) {
            struct timespec ts = to_ts(wake - now);
            r = ppoll(pf, (nfds_t)nfds, &ts, NULL);
        } else {
            struct timespec ts = to_ts(wake);
            r = -clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
            errno = -r;
        }
        if (r > 0)
            break;
        if (r < 0 && errno == EINTR) {
            interrupted = 1;
            break;
        }
        if (r < 0) /* (EINVAL, ENOMEM: nothing the loop can do about it but look again) */
            break;
    }
    while (r <= 0 && !interrupted && mono_ns() < deadline) /* the spin: to the deadline itself */
        if (nfds)
            r = poll(pf, (nfds_t)nfds, 0);
    if (r <= 0 && !interrupted && nfds) /* a deadline already past: what is ready still is */
        r = poll(pf, (nfds_t)nfds, 0);
    Py_END_ALLOW_THREADS;
    if (interrupted && PyErr_CheckSignals() < 0)
        return NULL;
    if (r > 0)
        return ready_fds(pf, nfds);
    return PyList_New(0);
}

/* timerslack(ns) -> the thread's previous timer slack (ns); ns 0 reads it only */
static PyObject *pace_timerslack(PyObject *self, PyObject *arg)
{
    (void)self;
    long ns = PyLong_AsLong(arg);
    if (ns == -1 && PyErr_Occurred())
        return NULL;
    int old = prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0);
    if (ns > 0 && prctl(PR_SET_TIMERSLACK, (unsigned long)ns, 0, 0, 0) != 0)
        return PyErr_SetFromErrno(PyExc_OSError);
    return PyLong_FromLong(old);
}

/* mlockall() -> 0, or the errno of mlockall(MCL_CURRENT | MCL_FUTURE) (EPERM, ENOMEM: the limit) */
static PyObject *pace_mlockall(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return PyLong_FromLong(mlockall(MCL_CURRENT | MCL_FUTURE) == 0 ? 0 : errno);
}

static PyObject *pace_munlockall(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    munlockall();
    Py_RETURN_NONE;
}

static PyObject *pace_now(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return PyLong_FromLongLong(mono_ns());
}

/* thread_mark() -> (CLOCK_MONOTONIC ns, the calling thread's CPU ns, its voluntary context switches):
 * the loop's state at each wait's start and return (rig/pace/late.py). In C: one getrusage, where
 * Python's made a 16-field result per call (2.3 µs a mark, two marks a wait). */
static PyObject *pace_thread_mark(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    struct rusage r;
    if (getrusage(RUSAGE_THREAD, &r) != 0)
        return PyErr_SetFromErrno(PyExc_OSError);
    long long cpu = ((long long)r.ru_utime.tv_sec + r.ru_stime.tv_sec) * 1000000000LL +
                    ((long long)r.ru_utime.tv_usec + r.ru_stime.tv_usec) * 1000LL;
    return Py_BuildValue("(LLl)", (long long)mono_ns(), cpu, r.ru_nvcsw);
}

static PyMethodDef methods[] = {
    { "wait", (PyCFunction)(void (*)(void))pace_wait, METH_FASTCALL, "wait(deadline_ns, fds, spin_ns)" },
    { "timerslack", pace_timerslack, METH_O, "timerslack(ns) -> previous" },
    { "mlockall", pace_mlockall, METH_NOARGS, "mlockall() -> 0 or errno" },
    { "munlockall", pace_munlockall, METH_NOARGS, "munlockall()" },
    { "now", pace_now, METH_NOARGS, "CLOCK_MONOTONIC in ns" },
    { "thread_mark", pace_thread_mark, METH_NOARGS,
      "thread_mark() -> (monotonic ns, thread CPU ns, voluntary switches)" },
    { NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_rigpace", "the real-time loop's wait", -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__rigpace(void) { return PyModule_Create(&module); }
