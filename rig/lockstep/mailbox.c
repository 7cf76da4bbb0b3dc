/*
 * The session's side of the mailboxes (rig/shim/ring.h: why, and the layout): a lockstep connection's
 * messages through shared memory, its socket kept for the ends and for waking the session's loop.
 * Included by fastpath.c (after fast_state); pump.c reads and waits through it, send_all replies
 * through it, and rig/session.py opens, reads, writes and closes them (the mailbox_* calls below).
 *
 * The session's waits: in pump (mbox_wait) it sleeps on the page's wake_seq, a futex every DUT process
 * bumps after it puts a message, with session_state = FUTEX; before each sleep it looks, without
 * waiting, at the loop's epoll set (the keeper, the listener, the ptys, another socket), and it sleeps
 * at most MBOX_SLICE_NS at a time, so that a DUT that ended (nothing bumps the word then) is seen
 * within a slice. Out of pump the state is POLL: a process that puts a message then also sends a byte on
 * its socket, which wakes the loop's epoll, and the loop looks at every mailbox before it sleeps
 * (mailbox_ready).
 */
#include <fcntl.h>
#include <sys/epoll.h>
#include <sys/mman.h>

#include "ring.h"

#define MBOX_MAX 64              /* connections with a mailbox at once; more keep their socket */
#define MBOX_SLICE_NS 2000000ull /* the longest futex sleep in pump: how late an ended DUT is seen */
#define MBOX_GLANCE_EVERY 64     /* messages taken without a sleep between looks at the loop's descriptors */

typedef struct {
    int fd;                /* the connection's socket */
    struct rig_mailbox *m; /* mapped */
    uint64_t tail;         /* up: read so far (the session's own count: the shared one is only told) */
    uint64_t head;         /* down: written so far */
} mbox_slot;

struct mbox_table {
    struct rig_shm *page;
    int n;
    mbox_slot slot[MBOX_MAX];
};

static void mbox_release(struct mbox_table *t)
{
    if (!t)
        return;
    for (int i = 0; i < t->n; i++)
        munmap(t->slot[i].m, sizeof *t->slot[i].m);
    PyMem_Free(t);
}

static mbox_slot *mbox_find(struct mbox_table *t, int fd)
{
    for (int i = 0; t && i < t->n; i++)
        if (t->slot[i].fd == fd)
            return &t->slot[i];
    return NULL;
}

/* (the fence: the rings' heads are read after this store on every architecture, not only x86's) */
static void mbox_set_state(struct mbox_table *t, uint32_t state)
{
    __atomic_store_n(&t->page->session_state, state, __ATOMIC_SEQ_CST);
    __atomic_thread_fence(__ATOMIC_SEQ_CST);
}

/* The up ring's bytes (at most room) into out: their count, or -1 for a broken ring. The head is read
   once: the DUT may move it meanwhile, and only what it said at that read is taken. */
static Py_ssize_t mbox_take(mbox_slot *mb, uint8_t *out, Py_ssize_t room)
{
    int64_t used = ring_used(&mb->m->up, mb->tail);
    if (used <= 0)
        return (Py_ssize_t)used;
    Py_ssize_t n = used < room ? (Py_ssize_t)used : room;
    ring_copy_out(mb->m->up_data, mb->tail, out, (size_t)n);
    mb->tail += (uint64_t)n;
    __atomic_store_n(&mb->m->up.tail, mb->tail, __ATOMIC_RELEASE);
    return n;
}

/* A reply, whole, into the down ring; the DUT woken if it sleeps. 0: no room (a DUT that does not read
   its replies), nothing written */
static int mbox_put(mbox_slot *mb, const uint8_t *p, size_t n)
{
    int64_t room = ring_room(&mb->m->down, mb->head);
    if (room < (int64_t)n)
        return 0;
    ring_copy_in(mb->m->down_data, mb->head, p, n);
    mb->head += n;
    ring_publish(&mb->m->down, mb->head);
    if (__atomic_load_n(&mb->m->down.sleeping, __ATOMIC_SEQ_CST))
        rig_futex_wake(&mb->m->down.seq);
    return 1;
}

/* 2: another mailbox has bytes (it goes first, as the loop would take it: one connection does not
   starve another); 1: mb has (or is broken: its reader says so); 0: none has */
static int mbox_any(struct mbox_table *t, mbox_slot *mb)
{
    for (int i = 0; i < t->n; i++)
        if (&t->slot[i] != mb && ring_used(&t->slot[i].m->up, t->slot[i].tail) != 0)
            return 2;
    return ring_used(&mb->m->up, mb->tail) != 0;
}

static uint64_t mono_ns(void); /* (events.c) */
static int read_pty(PyObject *pair);
static PyObject *pty_of(PyObject *ptys, int fd);

/* fd's bells (zero bytes a process sent while the session was in its loop) taken off its socket: 1;
   0 when anything else is there (other bytes, its end: the loop's read says what) */
static int mbox_drain_bells(int fd)
{
    uint8_t bells[256];
    ssize_t k = recv(fd, bells, sizeof bells, MSG_PEEK | MSG_DONTWAIT);
    if (k <= 0)
        return k < 0 && (errno == EAGAIN || errno == EINTR);
    for (ssize_t i = 0; i < k; i++)
        if (bells[i])
            return 0;
    return recv(fd, bells, (size_t)k, MSG_DONTWAIT) == k;
}

/* The loop's epoll set looked at without waiting: a pty's bytes are read and fd's bells taken (as the
   loop would); 1 when another descriptor is ready, else 2 when fd's socket has anything but bells
   (its end, other bytes: the loop's read), 0 when nothing is, -1 a Python error */
static int mbox_glance(int epfd, int fd, PyObject *ptys)
{
    struct epoll_event ev[8];
    int ready = epoll_wait(epfd, ev, 8, 0), r = 0;
    for (int i = 0; i < ready; i++) {
        PyObject *pty = ev[i].data.fd == fd ? NULL : pty_of(ptys, ev[i].data.fd);
        if (pty && read_pty(pty) < 0)
            return -1;
        if (!pty && (ev[i].data.fd != fd || !mbox_drain_bells(fd)))
            r = ev[i].data.fd != fd || r == 1 ? 1 : 2;
    }
    return r;
}

/* pump's wait for fd's next message: 1 when its mailbox has bytes; 0 when the loop's turn has come
   (another connection's message, another descriptor ready, until reached); 2 when fd's socket is
   ready (bells or its end: the loop's read); -1 a Python error. spin_ns: polled that long before it
   sleeps (--spin). The loop's other descriptors are looked at before each sleep, and after every
   MBOX_GLANCE_EVERY messages taken without one (a DUT on a core of its own may never let the session
   sleep). */
static int mbox_wait(struct mbox_table *t, mbox_slot *mb, int epfd, int fd, PyObject *ptys, uint64_t until,
                     uint64_t spin_ns, unsigned *unglanced)
{
    uint32_t *word = &t->page->wake_seq;
    uint64_t spin_until = spin_ns ? mono_ns() + spin_ns : 0;
    for (;;) {
        if (PyErr_CheckSignals() < 0)
            return -1;
        uint32_t seen = __atomic_load_n(word, __ATOMIC_SEQ_CST);
        int any = mbox_any(t, mb);
        uint64_t now = mono_ns();
        if (now >= until || any == 2)
            return 0;
        if (any == 1 && ++*unglanced < MBOX_GLANCE_EVERY)
            return 1;
        if (!any && spin_until && now < spin_until)
            continue;
        spin_until = 0;
        int glance = mbox_glance(epfd, fd, ptys);
        *unglanced = 0;
        if (glance)
            return glance == 1 ? 0 : glance;
        if (any)
            return 1;
        mbox_set_state(t, RIG_SESSION_FUTEX);
        if (!mbox_any(t, mb)) {
            uint64_t slice = until - now < MBOX_SLICE_NS ? until - now : MBOX_SLICE_NS;
            PyThreadState *saved = PyEval_SaveThread(); /* (other Python threads run while it waits) */
            rig_futex_wait(word, seen, slice);
            PyEval_RestoreThread(saved);
        }
        mbox_set_state(t, RIG_SESSION_RUNNING);
    }
}

/* ---- the calls rig/session.py makes ---- */

static struct mbox_table *mbox_table_of(PyObject *capsule)
{
    fast_state *s = PyCapsule_GetPointer(capsule, "rig.lockstep");
    if (!s)
        return NULL;
    if (!s->mboxes) {
        if (!(s->mboxes = PyMem_Calloc(1, sizeof *s->mboxes)))
            return (void *)PyErr_NoMemory();
        s->mboxes->page = (struct rig_shm *)s->page.buf;
    }
    return s->mboxes;
}

/* mailbox_open(state, fd) -> a memfd holding connection fd's new mailbox, for its HELLO reply (the
   caller closes it); -1 when MBOX_MAX are open (the connection keeps its socket) */
static PyObject *fp_mailbox_open(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 2)
        return PyErr_Format(PyExc_TypeError, "mailbox_open takes 2 arguments");
    struct mbox_table *t = mbox_table_of(a[0]);
    int fd = (int)PyLong_AsLong(a[1]);
    if (!t || PyErr_Occurred())
        return NULL;
    if (t->n == MBOX_MAX || mbox_find(t, fd))
        return PyLong_FromLong(-1);
    /* sealed at its size: a DUT that shrank it would make the session's next look a SIGBUS */
    int mfd = memfd_create("rig-mailbox", MFD_CLOEXEC | MFD_ALLOW_SEALING);
    if (mfd < 0 || ftruncate(mfd, sizeof(struct rig_mailbox)) < 0 ||
        fcntl(mfd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) < 0) {
        PyErr_SetFromErrno(PyExc_OSError);
        if (mfd >= 0)
            close(mfd);
        return NULL;
    }
    struct rig_mailbox *m = mmap(NULL, sizeof *m, PROT_READ | PROT_WRITE, MAP_SHARED, mfd, 0);
    if (m == MAP_FAILED) {
        close(mfd);
        return PyErr_SetFromErrno(PyExc_OSError);
    }
    m->magic = RIG_MAILBOX_MAGIC;
    m->ring_size = RIG_RING_SIZE;
    t->slot[t->n++] = (mbox_slot){ .fd = fd, .m = m };
    return PyLong_FromLong(mfd);
}

/* A call's connection: a[0] the state, a[1] the connection's fd, nargs as usage says. Its mailbox's
   slot (and table, in *table); NULL with the error set for a call of another shape or a connection
   without a mailbox. */
static mbox_slot *slot_arg(PyObject *const *a, Py_ssize_t nargs, Py_ssize_t want, const char *usage,
                           struct mbox_table **table)
{
    if (nargs != want) {
        PyErr_SetString(PyExc_TypeError, usage);
        return NULL;
    }
    struct mbox_table *t = mbox_table_of(a[0]);
    int fd = (int)PyLong_AsLong(a[1]);
    if (!t || PyErr_Occurred())
        return NULL;
    mbox_slot *mb = mbox_find(t, fd);
    if (!mb)
        PyErr_Format(PyExc_ValueError, "connection %d has no mailbox", fd);
    *table = t;
    return mb;
}

/* mailbox_close(state, fd): connection fd's mailbox unmapped (its connection is dropped) */
static PyObject *fp_mailbox_close(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    struct mbox_table *t;
    mbox_slot *mb = slot_arg(a, nargs, 2, "mailbox_close takes (state, fd)", &t);
    if (!mb)
        return NULL;
    munmap(mb->m, sizeof *mb->m);
    *mb = t->slot[--t->n];
    Py_RETURN_NONE;
}

/* mailbox_take(state, fd, buf) -> the bytes of fd's mailbox appended to buf; -1 for a broken ring */
static PyObject *fp_mailbox_take(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    struct mbox_table *t;
    mbox_slot *mb = slot_arg(a, nargs, 3, "mailbox_take takes (state, fd, bytearray)", &t);
    if (!mb)
        return NULL;
    if (!PyByteArray_Check(a[2]))
        return PyErr_Format(PyExc_TypeError, "mailbox_take takes (state, fd, bytearray)");
    int64_t used = ring_used(&mb->m->up, mb->tail);
    if (used <= 0)
        return PyLong_FromLongLong(used);
    Py_ssize_t had = PyByteArray_GET_SIZE(a[2]);
    if (PyByteArray_Resize(a[2], had + (Py_ssize_t)used) < 0)
        return NULL;
    /* (what the head says now, at most what it said above: the rest of the room is given back) */
    Py_ssize_t n = mbox_take(mb, (uint8_t *)PyByteArray_AS_STRING(a[2]) + had, (Py_ssize_t)used);
    if (PyByteArray_Resize(a[2], had + (n > 0 ? n : 0)) < 0)
        return NULL;
    return PyLong_FromSsize_t(n);
}

/* mailbox_put(state, fd, data) -> False when fd's down ring has no room for data (nothing written) */
static PyObject *fp_mailbox_put(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    struct mbox_table *t;
    mbox_slot *mb = slot_arg(a, nargs, 3, "mailbox_put takes (state, fd, data)", &t);
    if (!mb)
        return NULL;
    Py_buffer data;
    if (PyObject_GetBuffer(a[2], &data, PyBUF_SIMPLE) < 0)
        return NULL;
    int ok = mbox_put(mb, data.buf, (size_t)data.len);
    PyBuffer_Release(&data);
    return PyBool_FromLong(ok);
}

/* mailbox_ready(state) -> the connections whose mailbox has bytes (or is broken), after the session's
   state is POLL: the loop calls it before it sleeps in its epoll, which a byte on a socket then wakes */
static PyObject *fp_mailbox_ready(PyObject *self, PyObject *state)
{
    (void)self;
    struct mbox_table *t = mbox_table_of(state);
    if (!t)
        return NULL;
    mbox_set_state(t, RIG_SESSION_POLL);
    PyObject *fds = PyList_New(0);
    for (int i = 0; fds && i < t->n; i++) {
        if (ring_used(&t->slot[i].m->up, t->slot[i].tail) == 0)
            continue;
        PyObject *fd = PyLong_FromLong(t->slot[i].fd);
        if (!fd || PyList_Append(fds, fd) < 0)
            Py_CLEAR(fds);
        Py_XDECREF(fd);
    }
    return fds;
}

#define MAILBOX_METHODS                                                                                        \
    { "mailbox_open", (PyCFunction)(void (*)(void))fp_mailbox_open, METH_FASTCALL, "a connection's mailbox" }, \
        { "mailbox_close", (PyCFunction)(void (*)(void))fp_mailbox_close, METH_FASTCALL, "its end" },          \
        { "mailbox_take", (PyCFunction)(void (*)(void))fp_mailbox_take, METH_FASTCALL, "its bytes" },          \
        { "mailbox_put", (PyCFunction)(void (*)(void))fp_mailbox_put, METH_FASTCALL, "a reply into it" },      \
        { "mailbox_ready", fp_mailbox_ready, METH_O, "the mailboxes with bytes" },
