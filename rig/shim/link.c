/*
 * The link to the session: one Unix stream socket per process (connected on first use and again in a
 * fork's child), messages of protocol.h sent whole in one sendmsg, requests that wait for their reply
 * and notices that do not, and notes (free text for the run's report). Everything that crosses to the
 * session goes through here. Part of rigshim.c (one translation unit): see its top comment.
 */

static char sock_path[108];
static int ahead; /* lockstep: a sleep moved the clock in a notice the session has not answered yet */
static int sock = -1;
static pid_t sock_pid;
static char held[4096]; /* lockstep: notices not sent yet (hold_msg) */
static size_t held_len;
static uint64_t spin_ns; /* RIG_SPIN_NS: how long a request polls for its reply before it sleeps */

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

static void send_msg(uint16_t type, const void *payload, uint32_t len);

/* Connects on first use and again after fork (a child gets its own connection). Caller holds lock. */
static void ensure_connected(void)
{
    if (sock >= 0 && sock_pid == self_pid())
        return;
    if (sock >= 0)
        LOAD(close)(sock); /* the parent's connection, inherited by fork */
    held_len = 0;          /* (and what the parent held: the parent sends it) */
    sock = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_un addr = { .sun_family = AF_UNIX };
    strcpy(addr.sun_path, sock_path);
    if (sock < 0 || connect(sock, (struct sockaddr *)&addr, sizeof addr) < 0)
        die_session(strerror(errno));
    sock_pid = self_pid();
    uint32_t hello[2] = { RIG_PROTOCOL_VERSION, (uint32_t)sock_pid };
    send_msg(RIG_MSG_HELLO, hello, sizeof hello);
    struct rig_hdr h;
    if (recv_all(&h, sizeof h) < 0 || h.type != RIG_MSG_HELLO || h.len != 0)
        die_session("no HELLO reply");
    if (h.status)
        die_session("the session refused this shim's protocol version");
}

/* The iovecs whole, across signals and short writes. */
static void send_iov(struct iovec *iov, int n)
{
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
}

/* What is held (hold_msg), then header and payload, in one sendmsg: two sends would wake the session
   twice per message (once for a header it cannot act on yet), which in lockstep costs as much as the
   work itself. */
/* A message's header, stamped now (lockstep: the DUT's sim time; real time: 0). */
static struct rig_hdr header(uint16_t type, uint32_t len)
{
    return (struct rig_hdr){ .len = len, .type = type, .status = 0, .t_ns = lockstep ? now_peek() : 0 };
}

static void send_msg(uint16_t type, const void *payload, uint32_t len)
{
    struct rig_hdr h = header(type, len);
    struct iovec iov[3] = { { held, held_len }, { &h, sizeof h }, { (void *)payload, len } };
    held_len = 0;
    send_iov(iov[0].iov_len ? iov : iov + 1, (iov[0].iov_len ? 3 : 2) - (len ? 0 : 1));
}

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
   none) and at exit. In real time a notice goes at once. Caller holds lock. */
static void hold_msg(uint16_t type, const void *payload, uint32_t len)
{
    if (!lockstep || sizeof(struct rig_hdr) + len > sizeof held) {
        send_msg(type, payload, len);
        return;
    }
    struct rig_hdr h = header(type, len);
    if (held_len + sizeof h + len > sizeof held)
        send_held();
    memcpy(held + held_len, &h, sizeof h);
    memcpy(held + held_len + sizeof h, payload, len);
    held_len += sizeof h + len;
}

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
    struct timespec ts;
    LOAD(clock_gettime)(CLOCK_MONOTONIC, &ts);
    uint64_t until = (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec + spin_ns;
    for (;;) {
        ssize_t k = recvmsg(sock, m, MSG_DONTWAIT);
        if (k >= 0 || (errno != EAGAIN && errno != EINTR))
            return k;
        LOAD(clock_gettime)(CLOCK_MONOTONIC, &ts);
        if ((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec >= until)
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
    pthread_mutex_lock(&lock);
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
