/*
 * pump(): a DUT connection read and acted on in C for as long as nothing needs the session's Python
 * loop (included by fastpath.c, after handle_bytes).
 *
 * Why: in a lockstep flight the session wakes about twice per FC cycle for the DUT's next messages.
 * Each wake through the Python loop (the selector, recv, the connection's buffer, the watchdogs' clock
 * reads) cost about 20 k instructions: more than the fast path's own work on the messages it brought.
 *
 * How: buf's bytes (a partial message, usually none) move to a C buffer; then, for as long as the fast
 * path takes every message, the connection is read and its whole messages are acted on, and before
 * each next read the session's own epoll set is waited on (epfd, the selector the loop waits on:
 * level-triggered, so nothing it reports is lost to the loop), as the loop would: a message of another
 * connection that came meanwhile is not passed over for this one's. pump returns, with the bytes not acted on put
 * back in buf, when
 *   - a message is one for the Python handler (the loop acts on it next, from buf);
 *   - anything other than this connection and the DUT's ptys is ready: the keeper, the listener, another
 *     connection;
 *   - it has run for PUMP_BUDGET_NS (the loop's watchdogs), or nothing came in that time;
 *   - the connection ended (the loop's own read sees that again, and drops it).
 * A pty that is ready (the DUT's telemetry: the reference FC's 50 lines a second) is read here into its
 * bytearray of bytes not yet stamped (the session's _Pty.pending), as the loop's _read_pty would: the loop
 * woke for it about once every three FC cycles, for about 6 k instructions a cycle (run_instructions.py).
 * A pty that stays ready with nothing to read is passed over until the budget is spent, as in the loop.
 * A signal's Python handler runs in it (PyErr_CheckSignals), and an exception it raises comes out of
 * pump, as one raised by the fast path does.
 */
#include <sys/epoll.h>
#include <time.h>
#include <unistd.h>

#define PUMP_RX (1 << 18) /* as the loop's own recv */
#define PUMP_BUDGET_NS 20000000ull
#define PUMP_EVENTS 8
#define PUMP_PTY_READ 65536 /* as the loop's _read_pty */

/* buf = p[0:n] */
static int give_back(PyObject *buf, const uint8_t *p, Py_ssize_t n)
{
    if (PyByteArray_Resize(buf, n) < 0)
        return -1;
    if (n)
        memcpy(PyByteArray_AS_STRING(buf), p, (size_t)n);
    return 0;
}

/* ptys: a tuple of (master fd, bytearray) pairs, checked before anything is read */
static int pty_pairs_ok(PyObject *ptys)
{
    if (!PyTuple_Check(ptys)) {
        PyErr_SetString(PyExc_TypeError, "pump takes the ptys as a tuple of (fd, bytearray) pairs");
        return 0;
    }
    for (Py_ssize_t i = 0; i < PyTuple_GET_SIZE(ptys); i++) {
        PyObject *pair = PyTuple_GET_ITEM(ptys, i);
        if (!PyTuple_Check(pair) || PyTuple_GET_SIZE(pair) != 2 || !PyLong_Check(PyTuple_GET_ITEM(pair, 0)) ||
            !PyByteArray_Check(PyTuple_GET_ITEM(pair, 1))) {
            PyErr_SetString(PyExc_TypeError, "pump takes the ptys as a tuple of (fd, bytearray) pairs");
            return 0;
        }
    }
    return 1;
}

/* The pty pair of descriptor ``fd``, or NULL */
static PyObject *pty_of(PyObject *ptys, int fd)
{
    for (Py_ssize_t i = 0; i < PyTuple_GET_SIZE(ptys); i++) {
        PyObject *pair = PyTuple_GET_ITEM(ptys, i);
        if (PyLong_AsLong(PyTuple_GET_ITEM(pair, 0)) == fd)
            return pair;
    }
    return NULL;
}

/* What the pty has, appended to its bytearray (one read, as _read_pty: an error or nothing is no bytes) */
static int read_pty(PyObject *pair)
{
    int fd = (int)PyLong_AsLong(PyTuple_GET_ITEM(pair, 0));
    PyObject *into = PyTuple_GET_ITEM(pair, 1);
    Py_ssize_t had = PyByteArray_GET_SIZE(into);
    if (PyByteArray_Resize(into, had + PUMP_PTY_READ) < 0)
        return -1;
    ssize_t k = read(fd, PyByteArray_AS_STRING(into) + had, PUMP_PTY_READ);
    return PyByteArray_Resize(into, had + (k > 0 ? k : 0));
}

/* pump(state, fd, epfd, buf, ptys, spin_ns) -> the bytes received from fd; -1, with nothing done, when
 * there is no room for them in C or the connection ended before anything came (the loop's own read
 * takes it). spin_ns: how long to poll the epoll set before sleeping on it (--spin, rig/cores.py) */
static PyObject *fp_pump(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 6)
        return PyErr_Format(PyExc_TypeError, "pump takes 6 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    int fd = (int)PyLong_AsLong(a[1]);
    int epfd = (int)PyLong_AsLong(a[2]);
    PyObject *buf = a[3], *ptys = a[4];
    const uint64_t spin_ns = PyLong_AsUnsignedLongLong(a[5]);
    if (!s || PyErr_Occurred())
        return NULL;
    if (!PyByteArray_Check(buf))
        return PyErr_Format(PyExc_TypeError, "pump takes the connection's bytearray");
    if (!pty_pairs_ok(ptys))
        return NULL;
    Py_ssize_t n = PyByteArray_GET_SIZE(buf);
    if (n > PUMP_RX / 2)
        return PyLong_FromLong(-1);
    if (!s->rx && !(s->rx = PyMem_Malloc(PUMP_RX)))
        return PyErr_NoMemory();
    memcpy(s->rx, PyByteArray_AS_STRING(buf), (size_t)n);
    if (PyByteArray_Resize(buf, 0) < 0)
        return NULL;
    Py_ssize_t got = 0;
    const uint64_t until = mono_ns() + PUMP_BUDGET_NS;
    int readable = 1; /* the loop found fd readable: it is read before anything is waited on */
    mbox_slot *mb = mbox_find(s->mboxes, fd);
    unsigned unglanced = 0; /* (mailbox: messages taken since the loop's descriptors were looked at) */
    if (mb)
        mbox_set_state(s->mboxes, RIG_SESSION_RUNNING);
    for (;;) {
        if (PyErr_CheckSignals() < 0)
            goto fail;
        if (!readable && mb) { /* the mailbox's wait (mailbox.c) */
            int w = mbox_wait(s->mboxes, mb, epfd, fd, ptys, until, spin_ns, &unglanced);
            if (w < 0)
                goto fail;
            if (w == 2 && !got) { /* its socket (bells, the end), nothing came: the loop's own read */
                mbox_set_state(s->mboxes, RIG_SESSION_POLL);
                if (give_back(buf, s->rx, n) < 0)
                    return NULL;
                return PyLong_FromLong(-1);
            }
            if (w != 1)
                break;
        } else if (!readable) { /* the loop's set first: another connection's message is not passed over */
            uint64_t now = mono_ns();
            if (now >= until)
                break;
            struct epoll_event ev[PUMP_EVENTS];
            int ready = 0, wait_errno = 0, wait_ms = (int)((until - now + 999999) / 1000000);
            if (spin_ns) { /* --spin: polled for (the shim's recv_spinning says why) */
                const uint64_t spin_until = now + spin_ns < until ? now + spin_ns : until;
                while ((ready = epoll_wait(epfd, ev, PUMP_EVENTS, 0)) == 0 && mono_ns() < spin_until)
                    ;
                wait_errno = errno;
            }
            if (ready == 0) {
                PyThreadState *saved = PyEval_SaveThread(); /* (other Python threads run while it waits) */
                ready = epoll_wait(epfd, ev, PUMP_EVENTS, wait_ms);
                wait_errno = errno;
                PyEval_RestoreThread(saved);
            }
            if (ready < 0 && wait_errno == EINTR)
                continue; /* (its Python handler runs at the top) */
            if (ready <= 0)
                break;
            int others = 0, mine = 0;
            for (int i = 0; i < ready && !others; i++) {
                PyObject *pty = ev[i].data.fd == fd ? NULL : pty_of(ptys, ev[i].data.fd);
                mine |= ev[i].data.fd == fd;
                others |= ev[i].data.fd != fd && !pty;
                if (pty && read_pty(pty) < 0)
                    goto fail;
            }
            if (others)
                break;
            if (!mine)
                continue;
        }
        readable = 0;
        ssize_t k =
            mb ? mbox_take(mb, s->rx + n, PUMP_RX - n) : recv(fd, s->rx + n, (size_t)(PUMP_RX - n), MSG_DONTWAIT);
        if (mb && k == 0)
            continue; /* nothing yet (a bell): wait (a broken ring, -1, is the end: the loop's read says why) */
        if (k > 0) {
            got += k;
            n += k;
            int r;
            Py_ssize_t off = handle_bytes(s, fd, s->rx, 0, n, &r);
            if (r < 0) {
                if (mb)
                    mbox_set_state(s->mboxes, RIG_SESSION_POLL);
                give_back(buf, s->rx + off, n - off);
                return NULL;
            }
            memmove(s->rx, s->rx + off, (size_t)(n - off));
            n -= off;
            if (r == 0 || n > PUMP_RX / 2) /* one for the handler; or a message this large: the loop's */
                break;
            continue;
        }
        if (!mb && k < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK))
            continue;
        /* the end: what came before it goes to the loop; nothing came: the loop reads the end itself */
        if (mb)
            mbox_set_state(s->mboxes, RIG_SESSION_POLL);
        if (give_back(buf, s->rx, n) < 0)
            return NULL;
        return PyLong_FromSsize_t(got ? got : -1);
    }
    if (mb)
        mbox_set_state(s->mboxes, RIG_SESSION_POLL); /* (a message now rings the loop's epoll) */
    if (give_back(buf, s->rx, n) < 0)
        return NULL;
    return PyLong_FromSsize_t(got);
fail:
    if (mb)
        mbox_set_state(s->mboxes, RIG_SESSION_POLL);
    give_back(buf, s->rx, n);
    return NULL;
}
