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

static void die_session(const char *why)
{
    fprintf(stderr, "rigshim: lost the rig session (%s); stopping the program\n", why);
    _exit(125);
}

/* The whole buffer or -1, across signals and short transfers, in either direction. */
static int io_all(void *buf, size_t n, int sending)
{
    char *p = buf;
    while (n) {
        ssize_t k = sending ? send(sock, p, n, MSG_NOSIGNAL) : recv(sock, p, n, 0);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static int send_all(const void *buf, size_t n) { return io_all((void *)buf, n, 1); }
static int recv_all(void *buf, size_t n) { return io_all(buf, n, 0); }

static uint64_t now_peek(void) { return __atomic_load_n(&shm->sim_ns, __ATOMIC_SEQ_CST); }

static void send_msg(uint16_t type, const void *payload, uint32_t len);

/* Connects on first use and again after fork (a child gets its own connection). Caller holds lock. */
static void ensure_connected(void)
{
    if (sock >= 0 && sock_pid == self_pid())
        return;
    if (sock >= 0)
        LOAD(close)(sock); /* the parent's connection, inherited by fork */
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

/* Header and payload in one sendmsg: two sends would wake the session twice per message (once for a
   header it cannot act on yet), which in lockstep costs as much as the work itself. */
static void send_msg(uint16_t type, const void *payload, uint32_t len)
{
    struct rig_hdr h = { .len = len, .type = type, .status = 0, .t_ns = lockstep ? now_peek() : 0 };
    struct iovec iov[2] = { { .iov_base = &h, .iov_len = sizeof h }, { .iov_base = (void *)payload, .iov_len = len } };
    struct msghdr m = { .msg_iov = iov, .msg_iovlen = len ? 2 : 1 };
    size_t total = sizeof h + len;
    ssize_t k;
    do
        k = sendmsg(sock, &m, MSG_NOSIGNAL);
    while (k < 0 && errno == EINTR);
    if (k < 0)
        die_session("send failed");
    if ((size_t)k < total) { /* a short write (a full socket buffer): the rest byte-exactly */
        size_t done = (size_t)k;
        if (done < sizeof h && send_all((const char *)&h + done, sizeof h - done) < 0)
            die_session("send failed");
        size_t off = done > sizeof h ? done - sizeof h : 0;
        if (len > off && send_all((const char *)payload + off, len - off) < 0)
            die_session("send failed");
    }
}

/* One request, one reply. The reply payload (at most cap bytes) lands in out. Caller holds lock. */
static struct rig_hdr request(uint16_t type, const void *payload, uint32_t len, void *out, uint32_t cap)
{
    ensure_connected();
    send_msg(type, payload, len);
    struct rig_hdr h;
    if (recv_all(&h, sizeof h) < 0)
        die_session("no reply");
    if (h.type != type || h.len > cap)
        die_session("a reply that does not fit the request");
    if (h.len && recv_all(out, h.len) < 0)
        die_session("short reply");
    __atomic_store_n(&ahead, 0, __ATOMIC_RELEASE); /* the session has read everything before this */
    return h;
}

static void notice(uint16_t type, const void *payload, uint32_t len)
{
    pthread_mutex_lock(&lock);
    ensure_connected();
    send_msg(type, payload, len);
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
