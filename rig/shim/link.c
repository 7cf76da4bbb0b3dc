/*
 * The link to the session: one Unix stream socket per process (connected on first use and again in a
 * fork's child), messages of protocol.h sent whole in one sendmsg, requests that wait for their reply
 * and notices that do not, and notes (free text for the run's report). Everything that crosses to the
 * session goes through here. In lockstep the session may grant a mailbox at HELLO (ring.h): the same
 * messages then go through shared memory, and the socket only says that either side is gone and wakes
 * a session that sleeps in its loop. Part of rigshim.c (one translation unit): see its top comment.
 */
#include "ring.h"

static char sock_path[108];
static int ahead; /* lockstep: a sleep moved the clock in a notice the session has not answered yet */
static int sock = -1;
static pid_t sock_pid;
static char held[4096]; /* lockstep: notices not sent yet (hold_msg) */
static size_t held_len;
static uint64_t spin_ns;           /* RIG_SPIN_NS: how long a request polls for its reply before it sleeps */
static struct rig_mailbox *mbox;   /* lockstep: the mailbox the session granted (NULL: the socket) */
static uint64_t mbox_head;         /* up: the bytes this process wrote */
static uint64_t mbox_tail;         /* down: the bytes it read */
#define MBOX_CHECK_NS 100000000ull /* a wait on the mailbox looks at the socket this often: is it gone? */

static void die_session(const char *why)
{
    fprintf(stderr, "rigshim: lost the rig session (%s); stopping the program\n", why);
    _exit(125);
}

/* The whole buffer or -1, across signals and short reads. */
static int recv_all(void *buf, size_t n)
{
    char *p = buf;
    while (n) {
        ssize_t k = recv(sock, p, n, 0);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static uint64_t now_peek(void) { return __atomic_load_n(&shm->sim_ns, __ATOMIC_SEQ_CST); }

/* The mailbox's side of the shim. The session is gone when its end of the socket closed. */
static int session_gone(void)
{
    char c;
    ssize_t k = recv(sock, &c, 1, MSG_PEEK | MSG_DONTWAIT);
    return k == 0 || (k < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR);
}

static uint64_t mono_now(void)
{
    struct timespec ts;
    LOAD(clock_gettime)(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

/* Something for the session is there: wake it as it waits (protocol.h RIG_SESSION_*). ``bell``: a byte
   on the socket if it waits in its loop's epoll (what was sent on the socket rings that itself). A
   session asleep in pump on a mailbox wakes for a message on any socket too, so a process without a
   mailbox (a new one's HELLO) is not left for its slice. */
static void wake_session(int bell)
{
    __atomic_fetch_add(&shm->wake_seq, 1, __ATOMIC_SEQ_CST);
    uint32_t state = __atomic_load_n(&shm->session_state, __ATOMIC_SEQ_CST);
    if (state == RIG_SESSION_FUTEX) {
        rig_futex_wake(&shm->wake_seq);
    } else if (state == RIG_SESSION_POLL && bell) {
        char zero = 0;
        (void)send(sock, &zero, 1, MSG_DONTWAIT | MSG_NOSIGNAL); /* (a full socket has bells already) */
    }
}

/* The iovecs, whole, into the up ring; waits (rarely: the session empties the ring each time it reads)
   while it has no room. */
static void mbox_send_iov(const struct iovec *iov, int n)
{
    size_t total = 0;
    for (int i = 0; i < n; i++)
        total += iov[i].iov_len;
    if (total > RIG_RING_SIZE)
        die_session("a message larger than the mailbox");
    int64_t room;
    while ((room = ring_room(&mbox->up, mbox_head)) < (int64_t)total) {
        if (room < 0)
            die_session("a broken mailbox");
        wake_session(1);
        if (session_gone())
            die_session("the session closed the connection");
        struct timespec pause = { 0, 50000 };
        syscall(SYS_clock_nanosleep, CLOCK_MONOTONIC, 0, &pause, NULL); /* (real time, not the DUT's) */
    }
    for (int i = 0; i < n; i++) {
        ring_copy_in(mbox->up_data, mbox_head, iov[i].iov_base, iov[i].iov_len);
        mbox_head += iov[i].iov_len;
    }
    ring_publish(&mbox->up, mbox_head);
    wake_session(1);
}

/* Blocks until the down ring holds a reply's header: polled for spin_ns first (--spin), then asleep on
   the ring's futex, looking at the socket every MBOX_CHECK_NS (a session that died wakes no one). */
static void mbox_await(void)
{
    struct rig_ring_ctl *c = &mbox->down;
    const uint64_t until = spin_ns ? mono_now() + spin_ns : 0;
    uint64_t check = 0; /* when to look at the socket next (signals do not put it off) */
    for (;;) {
        uint32_t seen = __atomic_load_n(&c->seq, __ATOMIC_SEQ_CST);
        int64_t used = ring_used(c, mbox_tail);
        if (used < 0)
            die_session("a broken mailbox");
        if (used >= (int64_t)sizeof(struct rig_hdr))
            return;
        if (until && mono_now() < until)
            continue;
        __atomic_store_n(&c->sleeping, 1, __ATOMIC_SEQ_CST);
        __atomic_thread_fence(__ATOMIC_SEQ_CST); /* (the head is read after it, on any architecture) */
        if (ring_used(c, mbox_tail) == used)
            rig_futex_wait(&c->seq, seen, MBOX_CHECK_NS);
        __atomic_store_n(&c->sleeping, 0, __ATOMIC_RELAXED);
        uint64_t now = mono_now();
        if (!check)
            check = now + MBOX_CHECK_NS;
        if (now >= check) {
            if (session_gone())
                die_session("no reply");
            check = now + MBOX_CHECK_NS;
        }
    }
}

/* The reply to a request of this type from the down ring: its payload (at most cap bytes) into out. The
   session puts a reply in whole, so its header's arrival means all of it is there. */
static struct rig_hdr mbox_reply(uint16_t type, void *out, uint32_t cap)
{
    struct rig_hdr h;
    mbox_await();
    ring_copy_out(mbox->down_data, mbox_tail, &h, sizeof h);
    if (h.type != type || h.len > cap || ring_used(&mbox->down, mbox_tail) < (int64_t)(sizeof h + h.len))
        die_session("a reply that does not fit the request");
    ring_copy_out(mbox->down_data, mbox_tail + sizeof h, out, h.len);
    mbox_tail += sizeof h + h.len;
    __atomic_store_n(&mbox->down.tail, mbox_tail, __ATOMIC_RELEASE);
    return h;
}

/* The HELLO reply from the socket: its header, and the mailbox if the session granted one (the reply's
   payload says so: u32 RIG_HELLO_MAILBOX; its memfd comes with it). -1: no reply; 1: a mailbox granted
   whose descriptor did not arrive (this connection is of no use: the session reads it as a mailbox's). */
static int recv_hello(struct rig_hdr *h)
{
    union {
        struct cmsghdr align;
        char buf[CMSG_SPACE(sizeof(int))];
    } ctl;
    struct iovec iov = { h, sizeof *h };
    struct msghdr m = { .msg_iov = &iov, .msg_iovlen = 1, .msg_control = ctl.buf, .msg_controllen = sizeof ctl.buf };
    ssize_t k;
    do
        k = recvmsg(sock, &m, MSG_CMSG_CLOEXEC);
    while (k < 0 && errno == EINTR);
    if (k <= 0 || ((size_t)k < sizeof *h && recv_all((char *)h + k, sizeof *h - (size_t)k) < 0))
        return -1;
    int fd = -1;
    struct cmsghdr *cm = CMSG_FIRSTHDR(&m);
    if (cm && cm->cmsg_level == SOL_SOCKET && cm->cmsg_type == SCM_RIGHTS && cm->cmsg_len == CMSG_LEN(sizeof(int)))
        memcpy(&fd, CMSG_DATA(cm), sizeof fd);
    uint32_t granted = 0;
    if (h->len != 0 && (h->len != sizeof granted || recv_all(&granted, sizeof granted) < 0))
        return -1;
    if (!(granted & RIG_HELLO_MAILBOX)) {
        if (fd >= 0)
            LOAD(close)(fd);
        return 0;
    }
    if (fd < 0) /* (the kernel drops a descriptor past this process's limit of open files: MSG_CTRUNC) */
        return 1;
    void *p = mmap(NULL, sizeof *mbox, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    LOAD(close)(fd);
    if (p == MAP_FAILED || ((struct rig_mailbox *)p)->magic != RIG_MAILBOX_MAGIC ||
        ((struct rig_mailbox *)p)->ring_size != RIG_RING_SIZE)
        die_session("the session's mailbox cannot be mapped (a rig of another build?)");
    mbox = p;
    mbox_head = mbox_tail = 0;
    return 0;
}

static void send_msg(uint16_t type, const void *payload, uint32_t len);
static void hold_msg(uint16_t type, const void *payload, uint32_t len);

/* Connects on first use and again after fork (a child gets its own connection). Caller holds lock. */
static void ensure_connected(void)
{
    if (sock >= 0 && sock_pid == self_pid())
        return;
    if (sock >= 0)
        LOAD(close)(sock); /* the parent's connection, inherited by fork */
    if (mbox)
        munmap(mbox, sizeof *mbox); /* (and its mailbox) */
    mbox = NULL;
    held_len = 0; /* (and what the parent held: the parent sends it) */
    /* lockstep: a mailbox asked for (ring.h); a session that keeps to the socket sends no memfd. One
       granted whose descriptor did not arrive: connected again without asking, and the run told why */
    for (int ask = lockstep;; ask = 0) {
        sock = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        struct sockaddr_un addr = { .sun_family = AF_UNIX };
        strcpy(addr.sun_path, sock_path);
        if (sock < 0 || connect(sock, (struct sockaddr *)&addr, sizeof addr) < 0)
            die_session(strerror(errno));
        sock_pid = self_pid();
        uint32_t hello[3] = { RIG_PROTOCOL_VERSION, (uint32_t)sock_pid, RIG_HELLO_MAILBOX };
        send_msg(RIG_MSG_HELLO, hello, ask ? sizeof hello : 2 * sizeof hello[0]);
        struct rig_hdr h;
        int got = recv_hello(&h);
        if (got < 0 || h.type != RIG_MSG_HELLO)
            die_session("no HELLO reply");
        if (h.status)
            die_session("the session refused this shim's protocol version");
        if (got == 0 && ask == lockstep)
            return;
        if (got == 0) {
            static const char why[] = "a mailbox's descriptor did not reach this process (at its limit of open "
                                      "files?): its messages go through the socket";
            hold_msg(RIG_MSG_NOTE, why, sizeof why - 1);
            return;
        }
        LOAD(close)(sock);
    }
}

/* The iovecs whole, across signals and short writes. */
static void send_iov(struct iovec *iov, int n)
{
    if (mbox) {
        mbox_send_iov(iov, n);
        return;
    }
    while (n) {
        struct msghdr m = { .msg_iov = iov, .msg_iovlen = (size_t)n };
        ssize_t k = sendmsg(sock, &m, MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0)
            die_session("send failed");
        size_t done = (size_t)k;
        for (; n && done >= iov->iov_len; iov++, n--)
            done -= iov->iov_len;
        if (n) {
            iov->iov_base = (char *)iov->iov_base + done;
            iov->iov_len -= done;
        }
    }
    if (lockstep)
        wake_session(0); /* (a session asleep on the mailboxes' futex: wake_session) */
}

/* What is held (hold_msg), then header and payload, in one sendmsg: two sends would wake the session
   twice per message (once for a header it cannot act on yet), which in lockstep costs as much as the
   work itself. */
/* A message's stamp: now (lockstep: the DUT's sim time; real time: 0). */
static uint64_t stamp_now(void) { return lockstep ? now_peek() : 0; }

static void send_msg_at(uint16_t type, const void *payload, uint32_t len, uint64_t t_ns)
{
    struct rig_hdr h = { .len = len, .type = type, .status = 0, .t_ns = t_ns };
    struct iovec iov[3] = { { held, held_len }, { &h, sizeof h }, { (void *)payload, len } };
    held_len = 0;
    send_iov(iov[0].iov_len ? iov : iov + 1, (iov[0].iov_len ? 3 : 2) - (len ? 0 : 1));
}

static void send_msg(uint16_t type, const void *payload, uint32_t len) { send_msg_at(type, payload, len, stamp_now()); }

/* Sends what is held (hold_msg), if anything. Caller holds lock. */
static void send_held(void)
{
    if (held_len && sock >= 0 && sock_pid == self_pid()) {
        struct iovec iov = { held, held_len };
        send_iov(&iov, 1);
    }
    held_len = 0;
}

/* A notice. Lockstep: the notices (PWM writes, a sleep that went ahead, notes) wait here, each stamped
   when it was made, and go with the process's next message in the same sendmsg. A control loop's
   cycle (read the sensors, write four motors, sleep) then wakes the session once, for its one request,
   where each notice sent alone woke it again: in lockstep the session and the DUT take turns, so every
   wake-up is on the run's critical path. The session sees the same messages in the same order; none
   of them needs an answer, and nothing in the session moves on before the DUT's next message. They
   also go before the DUT looks at the outside world (catch_up), before a fork (the child starts with
   none) and at exit. In real time a notice goes at once. Caller holds lock. hold_msg_at: stamped t_ns
   (a promised write: the time its promise was checked at, which another thread may have moved on). */
static void hold_msg_at(uint16_t type, const void *payload, uint32_t len, uint64_t t_ns)
{
    if (!lockstep || sizeof(struct rig_hdr) + len > sizeof held) {
        send_msg_at(type, payload, len, t_ns);
        return;
    }
    struct rig_hdr h = { .len = len, .type = type, .status = 0, .t_ns = t_ns };
    if (held_len + sizeof h + len > sizeof held)
        send_held();
    memcpy(held + held_len, &h, sizeof h);
    memcpy(held + held_len + sizeof h, payload, len);
    held_len += sizeof h + len;
}

static void hold_msg(uint16_t type, const void *payload, uint32_t len) { hold_msg_at(type, payload, len, stamp_now()); }

/* send_held where the lock is not held yet: before the DUT looks outside, at fork, at the process's end.
   It only tries the lock: these calls may come from a signal handler (waitpid in SIGCHLD's, _exit)
   that interrupted this very thread inside the lock. Another holder is sending or requesting, which
   takes what is held with it. */
static void send_held_now(void)
{
    if (!__atomic_load_n(&held_len, __ATOMIC_RELAXED) || pthread_mutex_trylock(&lock))
        return;
    send_held();
    pthread_mutex_unlock(&lock);
}

/* With RIG_SPIN_NS (`--spin`: the session and the DUT on cores of their own): the reply polled for up to
   spin_ns of real time, as the session polls for the next request. A wake-up from sleep costs a pair of
   context switches, ~14 us on one core and ~90 us across two on these VMs (bench/roundtrip.c); a poll
   sees the reply within a microsecond or two. -1 (errno EAGAIN): none came, sleep for it. */
static ssize_t recv_spinning(struct msghdr *m)
{
    const uint64_t until = mono_now() + spin_ns;
    for (;;) {
        ssize_t k = recvmsg(sock, m, MSG_DONTWAIT);
        if (k >= 0 || (errno != EAGAIN && errno != EINTR))
            return k;
        if (mono_now() >= until)
            return -1;
    }
}

/* One request, one reply. The reply payload (at most cap bytes) lands in out. Caller holds lock. The
   session sends a reply whole and nothing else on this connection while a request waits, so one
   recvmsg into header and payload usually takes all of it: a second read per request was a tenth of
   the DUT's system calls. */
static struct rig_hdr request(uint16_t type, const void *payload, uint32_t len, void *out, uint32_t cap)
{
    ensure_connected();
    send_msg(type, payload, len);
    struct rig_hdr h;
    if (mbox) {
        h = mbox_reply(type, out, cap);
        __atomic_store_n(&ahead, 0, __ATOMIC_RELEASE); /* (as below) */
        return h;
    }
    struct iovec iov[2] = { { &h, sizeof h }, { out, cap } };
    struct msghdr m = { .msg_iov = iov, .msg_iovlen = cap ? 2 : 1 };
    ssize_t k = spin_ns ? recv_spinning(&m) : -1;
    if (k < 0)
        do
            k = recvmsg(sock, &m, 0);
        while (k < 0 && errno == EINTR);
    if (k <= 0 || ((size_t)k < sizeof h && recv_all((char *)&h + k, sizeof h - (size_t)k) < 0))
        die_session("no reply");
    size_t got = (size_t)k > sizeof h ? (size_t)k - sizeof h : 0;
    if (h.type != type || h.len > cap || got > h.len)
        die_session("a reply that does not fit the request");
    if (h.len > got && recv_all((char *)out + got, h.len - got) < 0)
        die_session("short reply");
    __atomic_store_n(&ahead, 0, __ATOMIC_RELEASE); /* the session has read everything before this */
    return h;
}

static void notice(uint16_t type, const void *payload, uint32_t len)
{
    LOAD(pthread_mutex_lock)(&lock);
    ensure_connected();
    hold_msg(type, payload, len);
    pthread_mutex_unlock(&lock);
}

static void note(const char *fmt, ...)
{
    char text[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    notice(RIG_MSG_NOTE, text, (uint32_t)(n < (int)sizeof text ? n : (int)sizeof text - 1));
}
