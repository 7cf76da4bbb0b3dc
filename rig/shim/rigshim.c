/*
 * rigshim: preloaded into an unmodified DUT (LD_PRELOAD) by `rig exec`. It redirects
 *   - /dev/i2c-N (the buses in RIG_I2C_BUSES) to the session's emulated bus,
 *   - /sys/class/pwm/pwmchip0/... to PWM channels kept in the shared page (and reported to the session),
 *   - chosen serial paths (RIG_SERIAL="/dev/ttyRC0=/dev/pts/5:...") to ptys the session owns,
 *   - in lockstep (RIG_LOCKSTEP=1), the clocks and every wait to the session's virtual time.
 * Everything else passes through to libc. Without RIG_SOCKET in the environment the shim does nothing.
 *
 * Why this shape: the kernel's i2c-dev, sysfs and clock behaviour is reproduced here, in the DUT's own
 * process, so that only the bytes of a transfer and the wish to wait cross the socket. Clock reads and
 * PWM writes never wait for the session (docs/design.md section 6).
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdio_ext.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/mman.h>
#include <sys/select.h>
#include <sys/sendfile.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/sysmacros.h>
#include <sys/time.h>
#include <sys/uio.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>
#include <wchar.h>

#include "protocol.h"

#define EXPORT __attribute__((visibility("default")))
#define MAX_FD 65536
#define MAX_SERIAL 8
#define I2C_MAJOR 89
#define MAX_XFER 8192 /* i2c-dev's limit for one message and for read()/write() */

/* ---------------------------------------------------------------- real libc functions */

#define REAL(name) real_##name
#define DECLARE_REAL(ret, name, ...) static ret (*real_##name)(__VA_ARGS__)
DECLARE_REAL(int, open, const char *, int, ...);
DECLARE_REAL(int, open64, const char *, int, ...);
DECLARE_REAL(int, openat, int, const char *, int, ...);
DECLARE_REAL(int, openat64, int, const char *, int, ...);
DECLARE_REAL(int, __open_2, const char *, int);
DECLARE_REAL(int, __open64_2, const char *, int);
DECLARE_REAL(int, __openat_2, int, const char *, int);
DECLARE_REAL(int, __openat64_2, int, const char *, int);
DECLARE_REAL(FILE *, fopen, const char *, const char *);
DECLARE_REAL(FILE *, fopen64, const char *, const char *);
DECLARE_REAL(int, close, int);
DECLARE_REAL(ssize_t, read, int, void *, size_t);
DECLARE_REAL(ssize_t, write, int, const void *, size_t);
DECLARE_REAL(ssize_t, pread, int, void *, size_t, off_t);
DECLARE_REAL(ssize_t, pwrite, int, const void *, size_t, off_t);
DECLARE_REAL(ssize_t, pread64, int, void *, size_t, off_t);
DECLARE_REAL(ssize_t, pwrite64, int, const void *, size_t, off_t);
DECLARE_REAL(off_t, lseek, int, off_t, int);
DECLARE_REAL(off_t, lseek64, int, off_t, int);
DECLARE_REAL(int, ioctl, int, unsigned long, ...);
DECLARE_REAL(int, dup, int);
DECLARE_REAL(int, dup2, int, int);
DECLARE_REAL(int, dup3, int, int, int);
DECLARE_REAL(int, fcntl, int, int, ...);
DECLARE_REAL(int, fcntl64, int, int, ...);
DECLARE_REAL(DIR *, opendir, const char *);
DECLARE_REAL(DIR *, fdopendir, int);
DECLARE_REAL(struct dirent *, readdir, DIR *);
DECLARE_REAL(struct dirent64 *, readdir64, DIR *);
DECLARE_REAL(int, closedir, DIR *);
DECLARE_REAL(int, dirfd, DIR *);
DECLARE_REAL(void, rewinddir, DIR *);
DECLARE_REAL(ssize_t, copy_file_range, int, off64_t *, int, off64_t *, size_t, unsigned int);
DECLARE_REAL(ssize_t, sendfile, int, int, off_t *, size_t);
DECLARE_REAL(ssize_t, sendfile64, int, int, off64_t *, size_t);
DECLARE_REAL(int, stat, const char *, struct stat *);
DECLARE_REAL(int, stat64, const char *, struct stat64 *);
DECLARE_REAL(int, lstat, const char *, struct stat *);
DECLARE_REAL(int, lstat64, const char *, struct stat64 *);
DECLARE_REAL(int, fstat, int, struct stat *);
DECLARE_REAL(int, fstat64, int, struct stat64 *);
DECLARE_REAL(int, fstatat, int, const char *, struct stat *, int);
DECLARE_REAL(int, fstatat64, int, const char *, struct stat64 *, int);
DECLARE_REAL(int, statx, int, const char *, int, unsigned int, struct statx *);
DECLARE_REAL(int, access, const char *, int);
DECLARE_REAL(int, faccessat, int, const char *, int, int);
DECLARE_REAL(int, clock_gettime, clockid_t, struct timespec *);
DECLARE_REAL(int, gettimeofday, struct timeval *, void *);
DECLARE_REAL(time_t, time, time_t *);
DECLARE_REAL(int, nanosleep, const struct timespec *, struct timespec *);
DECLARE_REAL(int, clock_nanosleep, clockid_t, int, const struct timespec *, struct timespec *);
DECLARE_REAL(int, usleep, useconds_t);
DECLARE_REAL(unsigned int, sleep, unsigned int);
DECLARE_REAL(int, poll, struct pollfd *, nfds_t, int);
DECLARE_REAL(int, ppoll, struct pollfd *, nfds_t, const struct timespec *, const sigset_t *);
DECLARE_REAL(int, select, int, fd_set *, fd_set *, fd_set *, struct timeval *);
DECLARE_REAL(int, pselect, int, fd_set *, fd_set *, fd_set *, const struct timespec *, const sigset_t *);
DECLARE_REAL(int, epoll_wait, int, struct epoll_event *, int, int);
DECLARE_REAL(int, epoll_pwait, int, struct epoll_event *, int, int, const sigset_t *);

static void *resolve(const char *name)
{
    void *p = dlsym(RTLD_NEXT, name);
    if (!p) {
        fprintf(stderr, "rigshim: libc has no %s\n", name);
        abort();
    }
    return p;
}
#define LOAD(name) ({ if (!real_##name) real_##name = resolve(#name); real_##name; })

/* ---------------------------------------------------------------- configuration */

static int errno_ret(int err)
{
    errno = err;
    return -1;
}

static int active;              /* RIG_SOCKET set: redirect */
static int lockstep;            /* RIG_LOCKSTEP=1: virtual time */
static char sock_path[108];
static unsigned i2c_buses_mask; /* bit N: /dev/i2c-N is emulated (N < 32) */
static int pwm_chip;
static struct rig_shm *shm;
static struct {
    char from[128];
    char to[128];
} serial_map[MAX_SERIAL];
static int n_serial;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static char fakes_dir[PATH_MAX]; /* RIG_FAKES: the session's folder of backing files (see open_fake) */
static int ahead; /* lockstep: a sleep moved the clock in a notice the session has not answered yet */
static int sock = -1;
static pid_t sock_pid;

static void parse_serial(const char *spec)
{
    while (spec && *spec && n_serial < MAX_SERIAL) {
        const char *end = strchr(spec, ':');
        size_t n = end ? (size_t)(end - spec) : strlen(spec);
        const char *eq = memchr(spec, '=', n);
        if (eq && (size_t)(eq - spec) < sizeof serial_map[0].from && n - (size_t)(eq - spec) - 1 < sizeof serial_map[0].to) {
            memcpy(serial_map[n_serial].from, spec, (size_t)(eq - spec));
            memcpy(serial_map[n_serial].to, eq + 1, n - (size_t)(eq - spec) - 1);
            n_serial++;
        }
        spec = end ? end + 1 : NULL;
    }
}

/* This process's pid, kept: getpid() is a syscall (glibc no longer caches it), and every message asks.
   Set at start-up and in a fork's child (pthread_atfork), so it is never 0 once the shim runs: a vfork
   child (Python's subprocess, between vfork and exec) shares the parent's memory, own_pid included,
   and tells itself apart by getpid() (see set_fake). posix_spawn children only exec. */
static pid_t own_pid;
static void reset_std_lock(void);
static void after_fork_child(void)
{
    own_pid = getpid();
    reset_std_lock();
}
static void adopt_inherited_fakes(void);
static pid_t self_pid(void)
{
    if (!own_pid)
        own_pid = getpid();
    return own_pid;
}

__attribute__((constructor)) static void shim_init(void)
{
    const char *s = getenv("RIG_SOCKET");
    if (!s || !*s || strlen(s) >= sizeof sock_path)
        return;
    strcpy(sock_path, s);
    const char *shm_path = getenv("RIG_SHM");
    int fd = shm_path ? LOAD(open)(shm_path, O_RDWR | O_CLOEXEC) : -1;
    if (fd < 0) {
        fprintf(stderr, "rigshim: cannot open the shared page RIG_SHM=%s: %s\n", shm_path ? shm_path : "(unset)",
                strerror(errno));
        return;
    }
    void *p = mmap(NULL, sizeof(struct rig_shm), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    LOAD(close)(fd);
    if (p == MAP_FAILED || ((struct rig_shm *)p)->magic != RIG_SHM_MAGIC) {
        fprintf(stderr, "rigshim: RIG_SHM=%s is not a rig shared page\n", shm_path);
        return;
    }
    shm = p;
    const char *b = getenv("RIG_I2C_BUSES");
    for (; b && *b; b++) {
        char *end;
        long n = strtol(b, &end, 10);
        if (end != b && n >= 0 && n < 32)
            i2c_buses_mask |= 1u << n;
        b = *end ? end : end - 1;
    }
    const char *chip = getenv("RIG_PWM_CHIP");
    pwm_chip = chip ? atoi(chip) : 0;
    parse_serial(getenv("RIG_SERIAL"));
    const char *ls = getenv("RIG_LOCKSTEP");
    lockstep = ls && strcmp(ls, "1") == 0;
    const char *fk = getenv("RIG_FAKES");
    if (fk && fk[0] == '/' && strlen(fk) < sizeof fakes_dir - 64)
        strcpy(fakes_dir, fk);
    own_pid = getpid();
    pthread_atfork(NULL, NULL, after_fork_child);
    active = 1;
    adopt_inherited_fakes();
}

/* ---------------------------------------------------------------- the socket */

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
    struct sockaddr_un addr = {.sun_family = AF_UNIX};
    strcpy(addr.sun_path, sock_path);
    if (sock < 0 || connect(sock, (struct sockaddr *)&addr, sizeof addr) < 0)
        die_session(strerror(errno));
    sock_pid = self_pid();
    uint32_t hello[2] = {RIG_PROTOCOL_VERSION, (uint32_t)sock_pid};
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
    struct rig_hdr h = {.len = len, .type = type, .status = 0, .t_ns = lockstep ? now_peek() : 0};
    struct iovec iov[2] = {{.iov_base = &h, .iov_len = sizeof h}, {.iov_base = (void *)payload, .iov_len = len}};
    struct msghdr m = {.msg_iov = iov, .msg_iovlen = len ? 2 : 1};
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

/* ---------------------------------------------------------------- time */

#define NS 1000000000ull

static uint64_t ts_ns(const struct timespec *ts) { return (uint64_t)ts->tv_sec * NS + (uint64_t)ts->tv_nsec; }
static void ns_ts(uint64_t ns, struct timespec *ts)
{
    ts->tv_sec = (time_t)(ns / NS);
    ts->tv_nsec = (long)(ns % NS);
}

static int virtual_clock(clockid_t id) { return active && lockstep && shm && id >= 0; }

/* Base of a clock at sim time 0, or -1 for clocks we leave alone. */
static int64_t clock_base(clockid_t id)
{
    switch (id) {
    case CLOCK_REALTIME:
    case CLOCK_REALTIME_COARSE:
    case CLOCK_TAI:
    case CLOCK_REALTIME_ALARM:
        return (int64_t)shm->epoch_ns;
    case CLOCK_MONOTONIC:
    case CLOCK_MONOTONIC_RAW:
    case CLOCK_MONOTONIC_COARSE:
    case CLOCK_BOOTTIME:
    case CLOCK_BOOTTIME_ALARM:
        return (int64_t)shm->mono_base_ns;
    case CLOCK_PROCESS_CPUTIME_ID:
    case CLOCK_THREAD_CPUTIME_ID:
        return 0; /* a busy program's CPU time is its virtual time */
    default:
        return -1;
    }
}

static uint32_t wait_until(uint64_t wake_ns, uint32_t kind);

_Static_assert(offsetof(struct rig_shm, limit_ns) == RIG_SHM_LIMIT_OFFSET, "RIG_SHM_LIMIT_OFFSET is wrong");

/* A clock read: the program ran a little, so time moves a quantum (busy loops still advance). Time
   moved by clock reads counts like any other: the read that reaches the run's end asks the session,
   which ends the run there (the request gets no answer), so a loop that only reads the clock cannot
   run past --duration or --sim-timeout. */
static uint64_t now_tick(void)
{
    uint64_t t = __atomic_add_fetch(&shm->sim_ns, shm->quantum_ns, __ATOMIC_SEQ_CST);
    uint64_t limit = __atomic_load_n(&shm->limit_ns, __ATOMIC_RELAXED);
    if (limit && t >= limit)
        wait_until(t, RIG_WAIT_SLEEP);
    return t;
}

/* Asks the session to run the world until wake_ns (or an event); returns why we woke. */
/* The WAIT payload: u64 wake_ns, u32 kind, u32 0. */
struct wait_req {
    uint64_t wake;
    uint32_t kind, zero;
};

/* Moves the shared clock forward to t_ns (never back: another thread may have moved it further). */
static void clock_advance_to(uint64_t t_ns)
{
    uint64_t cur = now_peek();
    while (t_ns > cur && !__atomic_compare_exchange_n(&shm->sim_ns, &cur, t_ns, 0, __ATOMIC_SEQ_CST, __ATOMIC_SEQ_CST))
        ;
}

static uint32_t wait_until(uint64_t wake_ns, uint32_t kind)
{
    struct wait_req req = {wake_ns, kind, 0};
    uint32_t reason = RIG_WAKE_DEADLINE;
    pthread_mutex_lock(&lock);
    struct rig_hdr h = request(RIG_MSG_WAIT, &req, sizeof req, &reason, sizeof reason);
    clock_advance_to(h.t_ns);
    pthread_mutex_unlock(&lock);
    return reason;
}

/* A sleep: nothing the session does can cut it short, so the outcome is known in advance. The first
   sleep after a request moves the clock itself and tells the session in a notice (RIG_WAIT_AHEAD): no
   round trip, which in a control loop (read sensors, write motors, sleep) is one of two per cycle.
   A second sleep in a row waits for the session as before, so a DUT that only sleeps cannot run ahead
   of it. Whatever the DUT looks at next syncs first (catch_up). */
static void sleep_until(uint64_t wake_ns)
{
    if (now_peek() < wake_ns && !__atomic_load_n(&ahead, __ATOMIC_ACQUIRE)) {
        struct wait_req req = {wake_ns, RIG_WAIT_AHEAD, 0};
        pthread_mutex_lock(&lock);
        ensure_connected();
        send_msg(RIG_MSG_WAIT, &req, sizeof req); /* stamped with the time the sleep began */
        clock_advance_to(wake_ns);
        __atomic_store_n(&ahead, 1, __ATOMIC_RELEASE);
        pthread_mutex_unlock(&lock);
        return;
    }
    while (now_peek() < wake_ns)
        wait_until(wake_ns, RIG_WAIT_SLEEP);
}

/* Before the DUT looks at anything outside the shim (a pty, a pipe, a file) after a sleep that went
   ahead: a plain WAIT to now, so the session has run the events of that sleep (written their bytes). */
static void catch_up(void)
{
    if (__atomic_load_n(&ahead, __ATOMIC_ACQUIRE) && virtual_clock(CLOCK_MONOTONIC))
        wait_until(now_peek(), RIG_WAIT_SLEEP);
}

static int valid_ts(const struct timespec *ts) { return ts && ts->tv_sec >= 0 && ts->tv_nsec >= 0 && ts->tv_nsec < (long)NS; }

EXPORT int clock_gettime(clockid_t id, struct timespec *ts)
{
    if (!virtual_clock(id) || clock_base(id) < 0)
        return LOAD(clock_gettime)(id, ts);
    ns_ts((uint64_t)clock_base(id) + now_tick(), ts);
    return 0;
}

EXPORT int gettimeofday(struct timeval *tv, void *tz)
{
    if (!virtual_clock(CLOCK_REALTIME))
        return LOAD(gettimeofday)(tv, tz);
    uint64_t ns = shm->epoch_ns + now_tick();
    tv->tv_sec = (time_t)(ns / NS);
    tv->tv_usec = (suseconds_t)(ns % NS / 1000);
    return 0;
}

EXPORT time_t time(time_t *out)
{
    if (!virtual_clock(CLOCK_REALTIME))
        return LOAD(time)(out);
    time_t t = (time_t)((shm->epoch_ns + now_tick()) / NS);
    if (out)
        *out = t;
    return t;
}

EXPORT int clock_nanosleep(clockid_t id, int flags, const struct timespec *req, struct timespec *rem)
{
    if (!virtual_clock(id) || clock_base(id) < 0)
        return LOAD(clock_nanosleep)(id, flags, req, rem);
    if (id == CLOCK_THREAD_CPUTIME_ID)
        return EINVAL; /* as Linux */
    if (!valid_ts(req))
        return EINVAL;
    uint64_t wake;
    if (flags & TIMER_ABSTIME) {
        uint64_t abs = ts_ns(req), base = (uint64_t)clock_base(id);
        wake = abs > base ? abs - base : 0;
    } else {
        wake = now_peek() + ts_ns(req);
    }
    sleep_until(wake);
    if (rem && !(flags & TIMER_ABSTIME))
        rem->tv_sec = rem->tv_nsec = 0;
    return 0;
}

EXPORT int nanosleep(const struct timespec *req, struct timespec *rem)
{
    if (!virtual_clock(CLOCK_MONOTONIC))
        return LOAD(nanosleep)(req, rem);
    int err = clock_nanosleep(CLOCK_MONOTONIC, 0, req, rem);
    if (err) {
        errno = err;
        return -1;
    }
    return 0;
}

EXPORT int usleep(useconds_t us)
{
    if (!virtual_clock(CLOCK_MONOTONIC))
        return LOAD(usleep)(us);
    sleep_until(now_peek() + (uint64_t)us * 1000u);
    return 0;
}

EXPORT unsigned int sleep(unsigned int s)
{
    if (!virtual_clock(CLOCK_MONOTONIC))
        return LOAD(sleep)(s);
    sleep_until(now_peek() + (uint64_t)s * NS);
    return 0;
}

/* The waits with timeouts: look (without waiting) for a ready descriptor; if none, let sim time run
   to the deadline or the session's next event (data it writes to a pty), and look again. */
static uint64_t deadline_ms(int timeout_ms) { return timeout_ms < 0 ? RIG_WAIT_FOREVER : now_peek() + (uint64_t)timeout_ms * 1000000u; }

static int wait_done(uint64_t deadline)
{
    if (deadline != RIG_WAIT_FOREVER && now_peek() >= deadline)
        return 1;
    wait_until(deadline, RIG_WAIT_POLL);
    return 0;
}

EXPORT int poll(struct pollfd *fds, nfds_t n, int timeout)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || timeout == 0)
        return LOAD(poll)(fds, n, timeout);
    uint64_t deadline = deadline_ms(timeout);
    for (;;) {
        int r = LOAD(poll)(fds, n, 0);
        if (r != 0 || wait_done(deadline))
            return r;
    }
}

EXPORT int __poll_chk(struct pollfd *fds, nfds_t n, int timeout, size_t fdslen)
{
    (void)fdslen;
    return poll(fds, n, timeout);
}

EXPORT int ppoll(struct pollfd *fds, nfds_t n, const struct timespec *tmo, const sigset_t *mask)
{
    static const struct timespec zero = {0, 0};
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || (tmo && tmo->tv_sec == 0 && tmo->tv_nsec == 0))
        return LOAD(ppoll)(fds, n, tmo, mask);
    if (tmo && !valid_ts(tmo)) {
        errno = EINVAL;
        return -1;
    }
    uint64_t deadline = tmo ? now_peek() + ts_ns(tmo) : RIG_WAIT_FOREVER;
    for (;;) {
        int r = LOAD(ppoll)(fds, n, &zero, mask);
        if (r != 0 || wait_done(deadline))
            return r;
    }
}

static int select_virtual(int nfds, fd_set *r, fd_set *w, fd_set *e, uint64_t deadline, const sigset_t *mask, int use_pselect)
{
    fd_set r0, w0, e0;
    if (r) r0 = *r;
    if (w) w0 = *w;
    if (e) e0 = *e;
    for (;;) {
        if (r) *r = r0;
        if (w) *w = w0;
        if (e) *e = e0;
        int res;
        if (use_pselect) {
            struct timespec zero = {0, 0};
            res = LOAD(pselect)(nfds, r, w, e, &zero, mask);
        } else {
            struct timeval zero = {0, 0};
            res = LOAD(select)(nfds, r, w, e, &zero);
        }
        if (res != 0 || wait_done(deadline))
            return res;
    }
}

EXPORT int select(int nfds, fd_set *r, fd_set *w, fd_set *e, struct timeval *tmo)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || (tmo && tmo->tv_sec == 0 && tmo->tv_usec == 0))
        return LOAD(select)(nfds, r, w, e, tmo);
    if (tmo && (tmo->tv_sec < 0 || tmo->tv_usec < 0)) {
        errno = EINVAL;
        return -1;
    }
    uint64_t deadline = tmo ? now_peek() + (uint64_t)tmo->tv_sec * NS + (uint64_t)tmo->tv_usec * 1000u : RIG_WAIT_FOREVER;
    int res = select_virtual(nfds, r, w, e, deadline, NULL, 0);
    if (tmo && res >= 0)
        tmo->tv_sec = tmo->tv_usec = 0; /* Linux reports the time left; a woken select is close enough to 0 */
    return res;
}

EXPORT int pselect(int nfds, fd_set *r, fd_set *w, fd_set *e, const struct timespec *tmo, const sigset_t *mask)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || (tmo && tmo->tv_sec == 0 && tmo->tv_nsec == 0))
        return LOAD(pselect)(nfds, r, w, e, tmo, mask);
    if (tmo && !valid_ts(tmo)) {
        errno = EINVAL;
        return -1;
    }
    return select_virtual(nfds, r, w, e, tmo ? now_peek() + ts_ns(tmo) : RIG_WAIT_FOREVER, mask, 1);
}

EXPORT int epoll_wait(int epfd, struct epoll_event *ev, int max, int timeout)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || timeout == 0)
        return LOAD(epoll_wait)(epfd, ev, max, timeout);
    uint64_t deadline = deadline_ms(timeout);
    for (;;) {
        int r = LOAD(epoll_wait)(epfd, ev, max, 0);
        if (r != 0 || wait_done(deadline))
            return r;
    }
}

EXPORT int epoll_pwait(int epfd, struct epoll_event *ev, int max, int timeout, const sigset_t *mask)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || timeout == 0)
        return LOAD(epoll_pwait)(epfd, ev, max, timeout, mask);
    uint64_t deadline = deadline_ms(timeout);
    for (;;) {
        int r = LOAD(epoll_pwait)(epfd, ev, max, 0, mask);
        if (r != 0 || wait_done(deadline))
            return r;
    }
}

/* ---------------------------------------------------------------- paths */

enum kind { K_NONE, K_I2C, K_PWM_ATTR, K_PWM_DIR, K_SERIAL };
enum pwm_attr { A_EXPORT, A_UNEXPORT, A_NPWM, A_PERIOD, A_DUTY, A_ENABLE, A_POLARITY };
#define N_ATTRS (A_POLARITY + 1)
static const char *const attr_names[N_ATTRS] = {"export", "unexport", "npwm", "period", "duty_cycle", "enable",
                                                "polarity"};

struct target {
    enum kind kind;
    int bus;         /* K_I2C */
    int channel;     /* K_PWM_*: -1 for the chip itself, -2 for /sys/class/pwm, -3 for its .. */
    enum pwm_attr attr;
    const char *to;  /* K_SERIAL: the pty */
};

static int parse_uint(const char *s, const char **end)
{
    if (*s < '0' || *s > '9')
        return -1;
    long v = 0;
    while (*s >= '0' && *s <= '9' && v < 100000)
        v = v * 10 + (*s++ - '0');
    *end = s;
    return (int)v;
}

/* The attribute "/name" among from..to-1, or N_ATTRS. */
static int attr_named(const char *rest, int from, int to)
{
    for (int a = from; rest[0] == '/' && a < to; a++)
        if (strcmp(rest + 1, attr_names[a]) == 0)
            return a;
    return N_ATTRS;
}

/* What a path names. A pwmN path exists only while the channel is exported, unless any_channel (a
   descriptor inherited across exec names its file even after an unexport, as an open file does). */
static struct target classify_path(const char *path, int any_channel)
{
    struct target t = {.kind = K_NONE};
    if (!active || !path)
        return t;
    const char *rest = "";
    if (strncmp(path, "/dev/i2c-", 9) == 0) {
        int n = parse_uint(path + 9, &rest);
        if (n >= 0 && n < 32 && *rest == 0 && (i2c_buses_mask >> n & 1u)) {
            t.kind = K_I2C;
            t.bus = n;
        }
        return t;
    }
    for (int i = 0; i < n_serial; i++)
        if (strcmp(path, serial_map[i].from) == 0) {
            t.kind = K_SERIAL;
            t.to = serial_map[i].to;
            return t;
        }
    size_t len = strlen(path);
    int up = len > 16 && strcmp(path + len - 3, "/..") == 0, here = len > 15 && strcmp(path + len - 2, "/.") == 0;
    if ((up || here) && strncmp(path, "/sys/class/pwm/", 15) == 0 && len < PATH_MAX) {
        /* the "." and ".." a listing shows (ls -la): the directory, or the one it is listed in (for
           /sys/class/pwm/.., a /sys/class that holds pwm alone: ls -l asks its extended attributes
           by this path, which only the shim knows) */
        char dir[PATH_MAX];
        memcpy(dir, path, len - (up ? 3 : 2));
        dir[len - (up ? 3 : 2)] = 0;
        struct target d = classify_path(dir, any_channel);
        if (d.kind != K_PWM_DIR || (up && d.channel == -3))
            return t;
        if (up)
            d.channel = d.channel >= 0 ? -1 : d.channel - 1;
        return d;
    }
    if (strcmp(path, "/sys/class/pwm") == 0 || strcmp(path, "/sys/class/pwm/") == 0) {
        t.kind = K_PWM_DIR;
        t.channel = -2;
        return t;
    }
    if (strncmp(path, "/sys/class/pwm/pwmchip", 22) != 0)
        return t;
    int chip = parse_uint(path + 22, &rest);
    if (chip != pwm_chip || !shm)
        return t;
    t.channel = -1;
    if (*rest == 0 || strcmp(rest, "/") == 0) {
        t.kind = K_PWM_DIR;
        return t;
    }
    int a = attr_named(rest, A_EXPORT, A_PERIOD);
    if (a != N_ATTRS) {
        t.kind = K_PWM_ATTR;
        t.attr = (enum pwm_attr)a;
        return t;
    }
    if (strncmp(rest, "/pwm", 4) != 0)
        return t;
    int ch = parse_uint(rest + 4, &rest);
    if (ch < 0 || ch >= (int)shm->npwm || (!any_channel && !shm->pwm[ch].exported))
        return t; /* not exported: the file does not exist (ENOENT from the real call) */
    t.channel = ch;
    if (*rest == 0 || strcmp(rest, "/") == 0) {
        t.kind = K_PWM_DIR;
        return t;
    }
    a = attr_named(rest, A_PERIOD, N_ATTRS);
    if (a != N_ATTRS) {
        t.kind = K_PWM_ATTR;
        t.attr = (enum pwm_attr)a;
    }
    return t;
}

static struct target classify(const char *path) { return classify_path(path, 0); }

/* The path a target is known by (the kernel's name for the file). */
static void target_path(const struct target *t, char *buf, size_t n)
{
    const char *sep = t->kind == K_PWM_ATTR ? "/" : "", *attr = t->kind == K_PWM_ATTR ? attr_names[t->attr] : "";
    if (t->kind == K_I2C)
        snprintf(buf, n, "/dev/i2c-%d", t->bus);
    else if (t->channel <= -2)
        snprintf(buf, n, t->channel == -2 ? "/sys/class/pwm" : "/sys/class");
    else if (t->channel == -1)
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d%s%s", pwm_chip, sep, attr);
    else
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d/pwm%d%s%s", pwm_chip, t->channel, sep, attr);
}

/* Only absolute paths are redirected (openat with a directory and a relative path passes through). */
static struct target classify_abs(const char *path)
{
    return path && path[0] == '/' ? classify(path) : (struct target){.kind = K_NONE};
}

static int is_empty(const char *path) { return path && path[0] == 0; }

static ino_t target_ino(const struct target *t)
{
    if (t->kind == K_I2C)
        return 1000 + (ino_t)t->bus;
    if (t->kind == K_PWM_DIR)
        return 2000 + (ino_t)(t->channel + 2); /* channel -2 is /sys/class/pwm, -3 its parent */
    return 3000 + (ino_t)(t->channel + 1) * 8 + (ino_t)t->attr;
}

/* A path the kernel would have that we only pretend: make it ENOENT-proof for stat/access. */
static void fill_stat(const struct target *t, struct stat *st)
{
    memset(st, 0, sizeof *st);
    st->st_uid = getuid();
    st->st_gid = getgid();
    st->st_nlink = 1;
    st->st_blksize = 4096;
    if (t->kind == K_I2C) {
        st->st_mode = S_IFCHR | 0660;
        st->st_rdev = makedev(I2C_MAJOR, t->bus);
        st->st_dev = makedev(0, 5);
    } else if (t->kind == K_PWM_DIR) {
        st->st_mode = S_IFDIR | 0755;
        st->st_nlink = 2;
    } else {
        int wo = t->attr == A_EXPORT || t->attr == A_UNEXPORT, ro = t->attr == A_NPWM;
        st->st_mode = S_IFREG | (wo ? 0200 : ro ? 0444 : 0644);
        st->st_size = 4096;
    }
    st->st_ino = target_ino(t);
}

/* ---------------------------------------------------------------- fake descriptors */

struct fake {
    struct target t;
    int addr;   /* I2C_SLAVE */
    int tenbit;
    off_t pos;  /* PWM attribute read position */
};
static struct fake *fakes[MAX_FD];

static struct fake *fake_of(int fd) { return (active && fd >= 0 && fd < MAX_FD) ? fakes[fd] : NULL; }

static void std_sync(int fd);

/* The table's one writer: fd is now f (NULL: not a fake). Then stdin/stdout/stderr follow (std_sync).
   Not in a vfork child: the table and stdout it would change are its parent's, whose descriptors have
   not changed (the child's dup2 onto 1 before exec would make the parent's fd 1 a fake). What the child
   execs finds its fakes from /proc/self/fd. */
static int set_fake(int fd, struct fake *f)
{
    if (getpid() != own_pid) {
        free(f);
        return 0;
    }
    pthread_mutex_lock(&lock);
    free(fakes[fd]);
    fakes[fd] = f;
    pthread_mutex_unlock(&lock);
    std_sync(fd);
    return 1;
}

/* A fake descriptor is a real one onto a file of its own in the session's folder (RIG_FAKES), named
   after the target's path with ':' for '/': its number is unique, close, dup, fcntl and poll work on
   it, and it says what it is across exec, where this table is lost: a shell opens the attribute and
   dup2s it onto 1, then execs echo, whose shim finds the fake again from /proc/self/fd
   (adopt_inherited_fakes). The file keeps the access mode asked for. The shim never writes to it:
   bytes there came through a call it cannot see (a raw syscall, writev, dprintf), and the session
   reports them. Without RIG_FAKES (an older session) the descriptor is onto /dev/null. */
static void backing_name(const struct target *t, char *buf, size_t n)
{
    target_path(t, buf, n);
    for (char *c = buf; *c; c++)
        if (*c == '/')
            *c = ':';
}

static int backing_open(const struct target *t, int flags)
{
    if (!fakes_dir[0])
        return LOAD(open)("/dev/null", O_RDWR | (flags & O_CLOEXEC));
    char path[PATH_MAX + 128], name[128];
    backing_name(t, name, sizeof name);
    snprintf(path, sizeof path, "%s/%s", fakes_dir, name);
    return LOAD(open)(path, (flags & (O_ACCMODE | O_CLOEXEC | O_NONBLOCK)) | O_CREAT, 0600);
}

static int open_fake(const struct target *t, int flags)
{
    int acc = flags & O_ACCMODE;
    if (t->kind == K_PWM_DIR && (acc != O_RDONLY || (flags & O_CREAT))) {
        errno = EISDIR;
        return -1;
    }
    if (t->kind != K_PWM_DIR && (flags & O_DIRECTORY)) {
        errno = ENOTDIR;
        return -1;
    }
    if (t->kind == K_PWM_ATTR) {
        int wo = t->attr == A_EXPORT || t->attr == A_UNEXPORT, ro = t->attr == A_NPWM;
        if ((wo && acc != O_WRONLY && getuid() != 0) || (ro && acc != O_RDONLY)) {
            errno = EACCES;
            return -1;
        }
    }
    int fd = backing_open(t, flags);
    if (fd < 0)
        return -1;
    if (fd >= MAX_FD) {
        LOAD(close)(fd);
        errno = EMFILE;
        return -1;
    }
    struct fake *f = calloc(1, sizeof *f);
    if (!f) {
        LOAD(close)(fd);
        errno = ENOMEM;
        return -1;
    }
    f->t = *t;
    f->addr = 0; /* i2c-dev's client starts at address 0, where nothing answers */
    if (set_fake(fd, f)) {
        /* Opening an emulated device is touching the devices, even when all that follows is a read or
           a write the kernel refuses (neither sends anything): connect, so the session knows. */
        pthread_mutex_lock(&lock);
        ensure_connected();
        pthread_mutex_unlock(&lock);
    }
    return fd;
}

static void drop_fake(int fd)
{
    if (fd >= 0 && fd < MAX_FD && fakes[fd])
        set_fake(fd, NULL);
}

/* `to` is now a copy of `from` (dup and friends): a fake's copy is a fake, anything else's is not. */
static void copy_fake(int from, int to)
{
    if (to < 0 || to >= MAX_FD)
        return;
    struct fake *src = fake_of(from), *f = NULL;
    if (src && (f = malloc(sizeof *f)))
        *f = *src;
    if (f || fakes[to])
        set_fake(to, f);
}

/* At start-up (after exec): the descriptors onto files in RIG_FAKES are fakes this process inherited.
   An I2C client's address and a read position start afresh (they live in the table, not the file). */
static void adopt_inherited_fakes(void)
{
    if (!fakes_dir[0])
        return;
    int dfd = LOAD(open)("/proc/self/fd", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0)
        return;
    size_t plen = strlen(fakes_dir);
    char buf[4096], link[PATH_MAX];
    long n;
    while ((n = syscall(SYS_getdents64, dfd, buf, sizeof buf)) > 0) {
        for (long off = 0; off < n;) {
            struct dirent64 *d = (struct dirent64 *)(buf + off);
            off += d->d_reclen;
            const char *end;
            int fd = parse_uint(d->d_name, &end);
            if (fd < 0 || *end || fd == dfd || fd >= MAX_FD)
                continue;
            ssize_t k = readlinkat(dfd, d->d_name, link, sizeof link - 1);
            if (k <= (ssize_t)plen + 1 || memcmp(link, fakes_dir, plen) != 0 || link[plen] != '/')
                continue;
            link[k] = 0;
            char *name = link + plen + 1;
            for (char *c = name; *c; c++)
                if (*c == ':')
                    *c = '/';
            struct target t = classify_path(name, 1);
            struct fake *f = t.kind == K_I2C || t.kind == K_PWM_ATTR || t.kind == K_PWM_DIR ? calloc(1, sizeof *f) : NULL;
            if (f) {
                f->t = t;
                set_fake(fd, f);
            }
        }
    }
    LOAD(close)(dfd);
}

/* ---------------------------------------------------------------- open and friends */

#define OPEN_MODE(flags, mode)                                                                                         \
    do {                                                                                                               \
        if ((flags) & (O_CREAT | __O_TMPFILE)) {                                                                       \
            va_list ap;                                                                                                \
            va_start(ap, flags);                                                                                       \
            mode = va_arg(ap, mode_t);                                                                                 \
            va_end(ap);                                                                                                \
        }                                                                                                              \
    } while (0)

static int redirect_open(const struct target *t, int flags, mode_t mode)
{
    if (t->kind == K_SERIAL)
        return LOAD(open)(t->to, flags, mode);
    return open_fake(t, flags);
}

EXPORT int open(const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(open)(path, flags, mode);
}

EXPORT int open64(const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(open64)(path, flags, mode);
}

EXPORT int openat(int dirfd, const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(openat)(dirfd, path, flags, mode);
}

EXPORT int openat64(int dirfd, const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(openat64)(dirfd, path, flags, mode);
}

EXPORT int __open_2(const char *path, int flags)
{
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__open_2)(path, flags);
}

EXPORT int __open64_2(const char *path, int flags)
{
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__open64_2)(path, flags);
}

EXPORT int __openat_2(int dirfd, const char *path, int flags)
{
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__openat_2)(dirfd, path, flags);
}

EXPORT int __openat64_2(int dirfd, const char *path, int flags)
{
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__openat64_2)(dirfd, path, flags);
}

static ssize_t fake_read(struct fake *f, void *buf, size_t n, off_t *pos);
static ssize_t fake_write(struct fake *f, const void *buf, size_t n);

/* stdio on a PWM attribute: glibc's fopen and fwrite use internal calls we cannot interpose, so the
   FILE gets our read/write through fopencookie. */
static ssize_t cookie_read(void *c, char *buf, size_t n)
{
    struct fake *f = fake_of((int)(intptr_t)c);
    return f ? fake_read(f, buf, n, &f->pos) : -1;
}
static ssize_t cookie_write(void *c, const char *buf, size_t n)
{
    struct fake *f = fake_of((int)(intptr_t)c);
    ssize_t r = f ? fake_write(f, buf, n) : -1;
    return r < 0 ? 0 : r; /* stdio treats a short write as the error */
}
static int cookie_seek(void *c, off64_t *off, int whence)
{
    struct fake *f = fake_of((int)(intptr_t)c);
    if (!f || whence != SEEK_SET || *off < 0)
        return -1;
    f->pos = *off;
    return 0;
}
static int cookie_close(void *c) { return close((int)(intptr_t)c); }

static FILE *redirect_fopen(const struct target *t, const char *mode, FILE *(*real)(const char *, const char *))
{
    if (t->kind == K_SERIAL)
        return real(t->to, mode);
    int flags = strchr(mode, '+') ? O_RDWR : mode[0] == 'r' ? O_RDONLY : O_WRONLY;
    if (strchr(mode, 'e'))
        flags |= O_CLOEXEC;
    int fd = open_fake(t, flags);
    if (fd < 0)
        return NULL;
    cookie_io_functions_t io = {cookie_read, cookie_write, cookie_seek, cookie_close};
    FILE *fp = fopencookie((void *)(intptr_t)fd, mode, io);
    if (!fp)
        close(fd);
    return fp;
}

EXPORT FILE *fopen(const char *path, const char *mode)
{
    struct target t = classify(path);
    return t.kind && t.kind != K_I2C ? redirect_fopen(&t, mode, LOAD(fopen)) : LOAD(fopen)(path, mode);
}

EXPORT FILE *fopen64(const char *path, const char *mode)
{
    struct target t = classify(path);
    return t.kind && t.kind != K_I2C ? redirect_fopen(&t, mode, LOAD(fopen64)) : LOAD(fopen64)(path, mode);
}

EXPORT int close(int fd)
{
    if (active && fd == sock && sock_pid == self_pid())
        return 0; /* a program closing every descriptor must not cut us off from the session */
    drop_fake(fd);
    return LOAD(close)(fd);
}

EXPORT int dup(int fd)
{
    int r = LOAD(dup)(fd);
    if (r >= 0)
        copy_fake(fd, r);
    return r;
}

EXPORT int dup2(int fd, int to)
{
    int r = LOAD(dup2)(fd, to);
    if (r >= 0 && fd != to)
        copy_fake(fd, r);
    return r;
}

EXPORT int dup3(int fd, int to, int flags)
{
    int r = LOAD(dup3)(fd, to, flags);
    if (r >= 0)
        copy_fake(fd, r);
    return r;
}

/* fcntl's F_DUPFD and F_DUPFD_CLOEXEC are dups too: shells save a descriptor they redirect that way
   (dash: fcntl(1, F_DUPFD_CLOEXEC, 10)) and dup2 it back afterwards. Programs built with 64-bit file
   offsets call fcntl64. The argument is an int or a pointer: passed on as it came. */
static int fcntl_via(int fd, int cmd, void *arg, int (*real)(int, int, ...))
{
    int r = real(fd, cmd, arg);
    if (r >= 0 && (cmd == F_DUPFD || cmd == F_DUPFD_CLOEXEC))
        copy_fake(fd, r);
    return r;
}

EXPORT int fcntl(int fd, int cmd, ...)
{
    va_list ap;
    va_start(ap, cmd);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    return fcntl_via(fd, cmd, arg, LOAD(fcntl));
}

EXPORT int fcntl64(int fd, int cmd, ...)
{
    va_list ap;
    va_start(ap, cmd);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    return fcntl_via(fd, cmd, arg, LOAD(fcntl64));
}

static off_t fake_seek(struct fake *f, off_t off, int whence);

/* ---------------------------------------------------------------- stdin, stdout, stderr on a fake */

/* glibc's stdio writes a FILE's buffer with an internal write() no preload can redirect. So bash's
   echo and printf (builtins printing on stdout after the shell dup2'd the attribute onto descriptor 1)
   and coreutils' echo (exec'd with it) would write to the backing file and report success. While
   descriptor 0, 1 or 2 is a fake, stdin/stdout/stderr is a cookie stream that goes through the shim
   (whose errors reach the caller: bash says "echo: write error: No such device"); when it stops being
   one, the program's own FILE is back. The swap keeps what a FILE would: pending output moves with
   it (a FILE writes what it holds to whatever its descriptor is at flush time), so do the error and
   end-of-file flags, and fileno() still answers 0, 1 or 2. A cookie is made once per descriptor and
   kept (the program may still hold its pointer), and writes to the real descriptor when that is not a
   fake. The program's fclose(stdout) closes the descriptor, as its own FILE would. */
struct std_stream {
    FILE *orig;   /* the program's FILE, while swapped */
    FILE *cookie;
    int swapped;
};
static struct std_stream stds[3];
static pthread_mutex_t std_lock = PTHREAD_MUTEX_INITIALIZER;
static void reset_std_lock(void) { pthread_mutex_init(&std_lock, NULL); }

static FILE **std_var(int fd) { return fd == 0 ? &stdin : fd == 1 ? &stdout : &stderr; }

static ssize_t std_read(void *c, char *buf, size_t n)
{
    int fd = (int)(intptr_t)c;
    struct fake *f = fake_of(fd);
    return f ? fake_read(f, buf, n, &f->pos) : LOAD(read)(fd, buf, n);
}

static ssize_t std_write(void *c, const char *buf, size_t n)
{
    int fd = (int)(intptr_t)c;
    struct fake *f = fake_of(fd);
    if (f) {
        ssize_t r = fake_write(f, buf, n);
        return r < 0 ? 0 : r; /* stdio takes a short write as the error; errno says which */
    }
    size_t done = 0;
    while (done < n) {
        ssize_t k = LOAD(write)(fd, buf + done, n - done);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            break;
        done += (size_t)k;
    }
    return (ssize_t)done;
}

static int std_seek(void *c, off64_t *off, int whence)
{
    int fd = (int)(intptr_t)c;
    struct fake *f = fake_of(fd);
    off_t r = f ? fake_seek(f, *off, whence) : LOAD(lseek)(fd, *off, whence);
    if (r < 0)
        return -1;
    *off = r;
    return 0;
}

static int std_close(void *c)
{
    int fd = (int)(intptr_t)c;
    struct std_stream *s = &stds[fd];
    if (*std_var(fd) == s->cookie)
        *std_var(fd) = s->orig;
    s->cookie = NULL; /* fclose frees it */
    s->swapped = 0;
    return close(fd);
}

static FILE *std_cookie(int fd, FILE *like)
{
    cookie_io_functions_t io = {std_read, std_write, std_seek, std_close};
    FILE *fp = fopencookie((void *)(intptr_t)fd, fd == 0 ? "r" : "w", io);
    if (!fp)
        return NULL;
    fp->_fileno = fd; /* glibc marks a cookie stream -2; any other number it leaves to fileno() */
    if (fd == 2)
        setvbuf(fp, NULL, _IONBF, 0);
    else if (fd == 1 && __flbf(like))
        setvbuf(fp, NULL, _IOLBF, BUFSIZ);
    return fp;
}

static void move_stream(FILE *from, FILE *to)
{
    size_t k = __fpending(from);
    if (k && fwide(from, 0) <= 0) {
        fwrite(from->_IO_write_base, 1, k, to);
        __fpurge(from);
    }
    int flags = from->_flags & (_IO_ERR_SEEN | _IO_EOF_SEEN);
    to->_flags = (to->_flags & ~(_IO_ERR_SEEN | _IO_EOF_SEEN)) | flags;
}

static void std_sync(int fd)
{
    if (fd < 0 || fd > 2 || (fake_of(fd) != NULL) == stds[fd].swapped)
        return;
    struct std_stream *s = &stds[fd];
    FILE **var = std_var(fd);
    pthread_mutex_lock(&std_lock);
    if (fake_of(fd) && !s->swapped) {
        FILE *cur = *var; /* only the stream that is on this descriptor (a program may point stdout elsewhere) */
        if (cur && cur != s->cookie && fileno(cur) == fd && (s->cookie || (s->cookie = std_cookie(fd, cur)))) {
            move_stream(cur, s->cookie);
            s->orig = cur;
            *var = s->cookie;
            s->swapped = 1;
        }
    } else if (!fake_of(fd) && s->swapped) {
        s->swapped = 0;
        if (*var == s->cookie) {
            move_stream(s->cookie, s->orig);
            *var = s->orig;
        } else {
            fflush(s->cookie);
        }
    }
    pthread_mutex_unlock(&std_lock);
}

/* ---------------------------------------------------------------- copies between descriptors */

/* copy_file_range (coreutils cat and cp, when both ends look like regular files): sysfs and i2c-dev
   share no file system with anything, so the kernel answers EXDEV and the caller falls back to read
   and write, which the shim sees. (Into the backing file the bytes would be lost.) */
EXPORT ssize_t copy_file_range(int in, off64_t *in_off, int out, off64_t *out_off, size_t len, unsigned int flags)
{
    if (fake_of(in) || fake_of(out))
        return errno_ret(EXDEV);
    return LOAD(copy_file_range)(in, in_off, out, out_off, len, flags);
}

/* sendfile (Python's shutil.copyfile) with a PWM attribute at either end: the kernel's copy, up to a
   page per call, through the shim's read and write. i2c-dev cannot splice: EINVAL. */
static ssize_t sendfile_fake(int out, int in, off64_t *off, size_t count)
{
    struct fake *fi = fake_of(in), *fo = fake_of(out);
    if ((fi && fi->t.kind != K_PWM_ATTR) || (fo && fo->t.kind != K_PWM_ATTR))
        return errno_ret(EINVAL);
    char buf[4096];
    size_t n = count < sizeof buf ? count : sizeof buf;
    off_t at = off ? *off : fi ? fi->pos : LOAD(lseek)(in, 0, SEEK_CUR), next = at;
    if (at < 0)
        return -1;
    ssize_t k = fi ? fake_read(fi, buf, n, &next) : LOAD(pread)(in, buf, n, at);
    if (k <= 0)
        return k;
    ssize_t w = fo ? fake_write(fo, buf, (size_t)k) : write(out, buf, (size_t)k);
    if (w <= 0)
        return w;
    at += w;
    if (off)
        *off = at;
    else if (fi)
        fi->pos = at;
    else
        LOAD(lseek)(in, at, SEEK_SET);
    return w;
}

EXPORT ssize_t sendfile(int out, int in, off_t *off, size_t count)
{
    if (fake_of(in) || fake_of(out))
        return sendfile_fake(out, in, (off64_t *)off, count);
    return LOAD(sendfile)(out, in, off, count);
}

EXPORT ssize_t sendfile64(int out, int in, off64_t *off, size_t count)
{
    if (fake_of(in) || fake_of(out))
        return sendfile_fake(out, in, off, count);
    return LOAD(sendfile64)(out, in, off, count);
}

/* ---------------------------------------------------------------- directories */

/* The pwm class's directories, listed as the kernel lists them: /sys/class/pwm holds pwmchip0, the chip
   export, npwm, unexport and pwmN for each exported channel, pwmN duty_cycle, enable, period and
   polarity. Only what the shim emulates is listed, so every name listed can be opened and stat'ed (a
   real chip also has device, power, subsystem and uevent, a channel capture, power and uevent).
   glibc's readdir reads a descriptor with getdents64, which no preload can redirect, so opendir and
   fdopendir on a fake give the shim's own stream; the calls taking a DIR tell one from a real DIR by
   the list of those open. The chip's channels are read when the stream opens or rewinds. */
struct fake_dir {
    struct fake_dir *next;
    int fd;
    struct target t;
    uint32_t exported; /* bit N: pwmN exported */
    long at;           /* the next entry */
    struct dirent64 ent;
};
_Static_assert(sizeof(struct dirent) == sizeof(struct dirent64), "struct dirent64 differs from struct dirent");
static struct fake_dir *fake_dirs;
static int n_fake_dirs;

static struct fake_dir *fake_dir_of(DIR *d)
{
    if (!__atomic_load_n(&n_fake_dirs, __ATOMIC_ACQUIRE))
        return NULL;
    pthread_mutex_lock(&lock);
    struct fake_dir *p = fake_dirs;
    while (p && (DIR *)p != d)
        p = p->next;
    pthread_mutex_unlock(&lock);
    return p;
}

static void dir_rewind(struct fake_dir *d)
{
    d->exported = 0;
    for (unsigned i = 0; i < shm->npwm && i < 32; i++)
        if (shm->pwm[i].exported)
            d->exported |= 1u << i;
    d->at = 0;
}

static DIR *dir_open(int fd, const struct target *t)
{
    struct fake_dir *d = calloc(1, sizeof *d);
    if (!d) {
        errno = ENOMEM;
        return NULL;
    }
    d->fd = fd;
    d->t = *t;
    dir_rewind(d);
    pthread_mutex_lock(&lock);
    d->next = fake_dirs;
    fake_dirs = d;
    __atomic_add_fetch(&n_fake_dirs, 1, __ATOMIC_RELEASE);
    pthread_mutex_unlock(&lock);
    return (DIR *)d;
}

/* Entry i of the directory into e (0: past the end). */
static int dir_entry(const struct fake_dir *d, long i, struct dirent64 *e)
{
    struct target c = d->t; /* what the entry names */
    const char *name = NULL;
    char buf[32];
    if (i < 2) {
        name = i ? ".." : ".";
        if (i)
            c.channel = c.channel >= 0 ? -1 : c.channel - 1;
    } else if (d->t.channel <= -2) {
        if (i > 2)
            return 0;
        c.channel = d->t.channel + 1;
        snprintf(buf, sizeof buf, "pwmchip%d", pwm_chip);
        name = c.channel == -1 ? buf : "pwm";
    } else if (d->t.channel == -1 && i < 2 + A_PERIOD) {
        c.kind = K_PWM_ATTR;
        c.attr = (enum pwm_attr)(i - 2);
        name = attr_names[c.attr];
    } else if (d->t.channel == -1) {
        long k = i - 2 - A_PERIOD;
        for (c.channel = 0; c.channel < 32; c.channel++)
            if ((d->exported >> c.channel & 1u) && k-- == 0)
                break;
        if (c.channel == 32)
            return 0;
        snprintf(buf, sizeof buf, "pwm%d", c.channel);
        name = buf;
    } else {
        if (i >= 2 + N_ATTRS - A_PERIOD)
            return 0;
        c.kind = K_PWM_ATTR;
        c.attr = (enum pwm_attr)(A_PERIOD + i - 2);
        name = attr_names[c.attr];
    }
    e->d_ino = target_ino(&c);
    e->d_off = i + 1;
    e->d_reclen = sizeof *e;
    e->d_type = c.kind == K_PWM_DIR ? DT_DIR : DT_REG;
    snprintf(e->d_name, sizeof e->d_name, "%s", name);
    return 1;
}

static struct dirent64 *dir_read(struct fake_dir *d)
{
    if (!dir_entry(d, d->at, &d->ent))
        return NULL; /* the end: errno unchanged */
    d->at++;
    return &d->ent;
}

EXPORT DIR *opendir(const char *path)
{
    struct target t = classify(path);
    if (t.kind == K_NONE || t.kind == K_SERIAL)
        return LOAD(opendir)(path);
    if (t.kind != K_PWM_DIR) {
        errno = ENOTDIR;
        return NULL;
    }
    int fd = open_fake(&t, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    DIR *d = dir_open(fd, &t);
    if (!d)
        close(fd);
    return d;
}

EXPORT DIR *fdopendir(int fd)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(fdopendir)(fd);
    if (f->t.kind != K_PWM_DIR) {
        errno = ENOTDIR;
        return NULL;
    }
    return dir_open(fd, &f->t);
}

EXPORT struct dirent *readdir(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    return d ? (struct dirent *)dir_read(d) : LOAD(readdir)(dir);
}

EXPORT struct dirent64 *readdir64(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    return d ? dir_read(d) : LOAD(readdir64)(dir);
}

EXPORT int closedir(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    if (!d)
        return LOAD(closedir)(dir);
    pthread_mutex_lock(&lock);
    for (struct fake_dir **p = &fake_dirs; *p; p = &(*p)->next)
        if (*p == d) {
            *p = d->next;
            break;
        }
    __atomic_sub_fetch(&n_fake_dirs, 1, __ATOMIC_RELEASE);
    pthread_mutex_unlock(&lock);
    int r = close(d->fd);
    free(d);
    return r;
}

EXPORT int dirfd(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    return d ? d->fd : LOAD(dirfd)(dir);
}

EXPORT void rewinddir(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    if (d)
        dir_rewind(d);
    else
        LOAD(rewinddir)(dir);
}

/* ---------------------------------------------------------------- stat and access */

static int stat_target(const char *path, struct stat *st, int (*real)(const char *, struct stat *))
{
    struct target t = classify(path);
    if (t.kind == K_SERIAL)
        return real(t.to, st);
    if (t.kind) {
        fill_stat(&t, st);
        return 0;
    }
    return real(path, st);
}

/* struct stat64 is struct stat on the 64-bit targets we build for; the casts below rely on it. */
_Static_assert(sizeof(struct stat) == sizeof(struct stat64), "struct stat64 differs from struct stat");
_Static_assert(sizeof(off_t) == sizeof(off64_t), "off64_t differs from off_t");
typedef int (*stat_fn)(const char *, struct stat *);
typedef int (*fstat_fn)(int, struct stat *);
typedef int (*fstatat_fn)(int, const char *, struct stat *, int);

EXPORT int stat(const char *path, struct stat *st) { return stat_target(path, st, LOAD(stat)); }
EXPORT int stat64(const char *path, struct stat64 *st) { return stat_target(path, (struct stat *)st, (stat_fn)LOAD(stat64)); }
EXPORT int lstat(const char *path, struct stat *st) { return stat_target(path, st, LOAD(lstat)); }
EXPORT int lstat64(const char *path, struct stat64 *st) { return stat_target(path, (struct stat *)st, (stat_fn)LOAD(lstat64)); }

static int fstat_fake(int fd, struct stat *st, int (*real)(int, struct stat *))
{
    struct fake *f = fake_of(fd);
    if (f) {
        fill_stat(&f->t, st);
        return 0;
    }
    return real(fd, st);
}

EXPORT int fstat(int fd, struct stat *st) { return fstat_fake(fd, st, LOAD(fstat)); }
EXPORT int fstat64(int fd, struct stat64 *st) { return fstat_fake(fd, (struct stat *)st, (fstat_fn)LOAD(fstat64)); }

static int fstatat_target(int dirfd, const char *path, struct stat *st, int flags,
                          int (*real)(int, const char *, struct stat *, int))
{
    if (is_empty(path) && (flags & AT_EMPTY_PATH))
        return fake_of(dirfd) ? (fill_stat(&fake_of(dirfd)->t, st), 0) : real(dirfd, path, st, flags);
    struct target t = classify_abs(path);
    if (t.kind == K_SERIAL)
        return real(dirfd, t.to, st, flags);
    if (t.kind) {
        fill_stat(&t, st);
        return 0;
    }
    return real(dirfd, path, st, flags);
}

EXPORT int fstatat(int dirfd, const char *path, struct stat *st, int flags) { return fstatat_target(dirfd, path, st, flags, LOAD(fstatat)); }
EXPORT int fstatat64(int dirfd, const char *path, struct stat64 *st, int flags)
{
    return fstatat_target(dirfd, path, (struct stat *)st, flags, (fstatat_fn)LOAD(fstatat64));
}

EXPORT int statx(int dirfd, const char *path, int flags, unsigned int mask, struct statx *sx)
{
    struct target t = classify_abs(path);
    if (is_empty(path) && (flags & AT_EMPTY_PATH) && fake_of(dirfd))
        t = fake_of(dirfd)->t;
    if (t.kind == K_SERIAL)
        return LOAD(statx)(dirfd, t.to, flags, mask, sx);
    if (!t.kind)
        return LOAD(statx)(dirfd, path, flags, mask, sx);
    struct stat st;
    fill_stat(&t, &st);
    memset(sx, 0, sizeof *sx);
    sx->stx_mask = STATX_BASIC_STATS;
    sx->stx_mode = (uint16_t)st.st_mode;
    sx->stx_nlink = (uint32_t)st.st_nlink;
    sx->stx_uid = st.st_uid;
    sx->stx_gid = st.st_gid;
    sx->stx_ino = st.st_ino;
    sx->stx_size = (uint64_t)st.st_size;
    sx->stx_blksize = (uint32_t)st.st_blksize;
    sx->stx_rdev_major = major(st.st_rdev);
    sx->stx_rdev_minor = minor(st.st_rdev);
    return 0;
}

static int access_target(const struct target *t, int amode)
{
    struct stat st;
    fill_stat(t, &st);
    if (((amode & X_OK) && !S_ISDIR(st.st_mode)) || ((amode & W_OK) && !(st.st_mode & 0200)) ||
        ((amode & R_OK) && !(st.st_mode & 0444) && getuid() != 0)) {
        errno = EACCES;
        return -1;
    }
    return 0;
}

EXPORT int access(const char *path, int amode)
{
    struct target t = classify(path);
    if (t.kind == K_SERIAL)
        return LOAD(access)(t.to, amode);
    return t.kind ? access_target(&t, amode) : LOAD(access)(path, amode);
}

EXPORT int faccessat(int dirfd, const char *path, int amode, int flags)
{
    struct target t = classify_abs(path);
    if (t.kind == K_SERIAL)
        return LOAD(faccessat)(dirfd, t.to, amode, flags);
    return t.kind ? access_target(&t, amode) : LOAD(faccessat)(dirfd, path, amode, flags);
}

/* ---------------------------------------------------------------- user memory */

/* The kernel copies a caller's memory with copy_from_user/copy_to_user: a bad address is EFAULT, never
   a crash. The shim does the same with process_vm_readv/process_vm_writev on its own pid (always
   allowed on oneself), every piece of one transfer in one call, so a transfer costs a syscall or two
   more, not one per buffer. Where those are not available (ENOSYS, or EPERM from a seccomp filter)
   it says so once and copies with memcpy, rejecting only addresses no user mapping has.
   Pieces that lie in the calling thread's live stack, between the shim's own frame and the stack's
   top, are mapped and writable whatever they hold, so they are copied with memcpy and cost nothing:
   a C driver's arguments, messages and buffers are usually there (the reference FC's all are, which
   saves it 4600 syscalls per 2 s of flight). A frame outside the thread's stack (a signal handler on
   an alternate stack, a coroutine's stack) takes the checked path. */
static int uaccess_memcpy;
static __thread uintptr_t stack_lo, stack_hi; /* this thread's stack, asked once (0, 0: unknown) */
static __thread int stack_asked;

static int on_live_stack(const struct iovec *remote, size_t nr)
{
    char here; /* in the shim's frame: the caller's live frames are all above it */
    if (!stack_asked) {
        stack_asked = 1;
        pthread_attr_t attr;
        void *addr;
        size_t size;
        if (pthread_getattr_np(pthread_self(), &attr) == 0) {
            if (pthread_attr_getstack(&attr, &addr, &size) == 0) {
                stack_lo = (uintptr_t)addr;
                stack_hi = (uintptr_t)addr + size;
            }
            pthread_attr_destroy(&attr);
        }
    }
    uintptr_t sp = (uintptr_t)&here;
    if (sp < stack_lo || sp >= stack_hi)
        return 0;
    for (size_t i = 0; i < nr; i++) {
        uintptr_t a = (uintptr_t)remote[i].iov_base;
        if (remote[i].iov_len && (a < sp || a + remote[i].iov_len < a || a + remote[i].iov_len > stack_hi))
            return 0;
    }
    return 1;
}

static int user_range(const void *p, size_t n)
{
    uintptr_t a = (uintptr_t)p;
    return n == 0 || (a >= 4096 && a + n > a && a + n <= (uintptr_t)1 << 47);
}

static size_t copy_by_memcpy(const struct iovec *local, size_t nl, const struct iovec *remote, size_t nr, int to_user)
{
    size_t li = 0, loff = 0;
    for (size_t i = 0; i < nr; i++) {
        if (!user_range(remote[i].iov_base, remote[i].iov_len))
            return i;
        for (size_t roff = 0; roff < remote[i].iov_len;) {
            while (li < nl && loff == local[li].iov_len) {
                li++;
                loff = 0;
            }
            if (li == nl)
                return i;
            size_t k = remote[i].iov_len - roff < local[li].iov_len - loff ? remote[i].iov_len - roff
                                                                          : local[li].iov_len - loff;
            char *r = (char *)remote[i].iov_base + roff, *l = (char *)local[li].iov_base + loff;
            memcpy(to_user ? r : l, to_user ? l : r, k);
            roff += k;
            loff += k;
        }
    }
    return nr;
}

/* Copies the caller's pieces (remote) into the shim's (local, the same bytes in total) or, to_user,
   back. Returns how many remote pieces, from the first, were copied whole: nr when all were. */
static size_t user_copy(const struct iovec *local, size_t nl, const struct iovec *remote, size_t nr, int to_user)
{
    size_t total = 0;
    for (size_t i = 0; i < nr; i++)
        total += remote[i].iov_len;
    if (total == 0)
        return nr;
    if (on_live_stack(remote, nr))
        return copy_by_memcpy(local, nl, remote, nr, to_user);
    if (!__atomic_load_n(&uaccess_memcpy, __ATOMIC_RELAXED)) {
        ssize_t k = to_user ? process_vm_writev(own_pid, local, nl, remote, nr, 0)
                            : process_vm_readv(own_pid, local, nl, remote, nr, 0);
        if (k >= 0 || (errno != ENOSYS && errno != EPERM)) {
            size_t done = k < 0 ? 0 : (size_t)k, i = 0;
            while (i < nr && remote[i].iov_len <= done)
                done -= remote[i++].iov_len;
            return i;
        }
        int err = errno;
        __atomic_store_n(&uaccess_memcpy, 1, __ATOMIC_RELAXED);
        note("process_vm_readv/writev refused (%s): the shim copies with memcpy, so a bad pointer handed to an "
             "emulated device may crash the command where the kernel says EFAULT", strerror(err));
    }
    return copy_by_memcpy(local, nl, remote, nr, to_user);
}

/* One piece: 0 or EFAULT. */
static int copy_in(void *dst, const void *user, size_t n)
{
    struct iovec l = {dst, n}, r = {(void *)user, n};
    return user_copy(&l, 1, &r, 1, 0) == 1 ? 0 : EFAULT;
}

static int copy_out(void *user, const void *src, size_t n)
{
    struct iovec l = {(void *)src, n}, r = {user, n};
    return user_copy(&l, 1, &r, 1, 1) == 1 ? 0 : EFAULT;
}

/* ---------------------------------------------------------------- I2C */

/* One transfer of messages whose buffers are the shim's (copied from the caller, or to be copied back):
   the read bytes land in them, and a RECV_LEN message's len becomes what it received (its count byte
   and the count), as the bus driver sets it. Returns 0 or an errno. */
static int i2c_transfer(struct fake *f, struct i2c_msg *msgs, unsigned n)
{
    static __thread unsigned char out[sizeof(struct rig_i2c_msg) * I2C_RDWR_IOCTL_MAX_MSGS + 4 + 8192 * 2];
    static __thread unsigned char in[8192 * 2 + 64];
    if (n == 0 || n > I2C_RDWR_IOCTL_MAX_MSGS)
        return EINVAL;
    size_t wlen = 0, rlen = 0;
    for (unsigned i = 0; i < n; i++) {
        if (msgs[i].len > MAX_XFER)
            return EINVAL;
        if (msgs[i].flags & I2C_M_RD)
            rlen += (msgs[i].flags & I2C_M_RECV_LEN) ? 1 + I2C_SMBUS_BLOCK_MAX : msgs[i].len;
        else
            wlen += msgs[i].len;
    }
    if (wlen > 2 * MAX_XFER || rlen > 2 * MAX_XFER)
        return EINVAL; /* more than the kernel would copy in one ioctl */
    uint16_t *hdr = (uint16_t *)out;
    hdr[0] = (uint16_t)f->t.bus;
    hdr[1] = (uint16_t)n;
    struct rig_i2c_msg *desc = (struct rig_i2c_msg *)(out + 4);
    unsigned char *data = out + 4 + n * sizeof *desc;
    for (unsigned i = 0; i < n; i++) {
        desc[i] = (struct rig_i2c_msg){msgs[i].addr, msgs[i].flags, msgs[i].len, 0};
        if (!(msgs[i].flags & I2C_M_RD) && msgs[i].len) {
            memcpy(data, msgs[i].buf, msgs[i].len);
            data += msgs[i].len;
        }
    }
    pthread_mutex_lock(&lock);
    struct rig_hdr h = request(RIG_MSG_I2C, out, (uint32_t)(data - out), in, sizeof in);
    if (lockstep && h.t_ns > now_peek())
        __atomic_store_n(&shm->sim_ns, h.t_ns, __ATOMIC_SEQ_CST); /* the bus time of the transfer */
    pthread_mutex_unlock(&lock);
    if (h.status)
        return h.status;
    size_t at = 0;
    for (unsigned i = 0; i < n; i++) {
        if (!(msgs[i].flags & I2C_M_RD))
            continue;
        size_t k = msgs[i].len;
        if (msgs[i].flags & I2C_M_RECV_LEN)
            msgs[i].len = (uint16_t)(k = at < h.len ? 1u + in[at] : 0);
        if (at + k > h.len)
            die_session("an I2C reply shorter than its request");
        memcpy(msgs[i].buf, in + at, k);
        at += k;
    }
    return 0;
}

/* I2C_RDWR as i2c-dev does it: the argument and the messages copied in, then for each message in order
   its length checked (EINVAL above 8192), its buffer copied in (EFAULT; read buffers too, and a zero
   length never faults) and a RECV_LEN message's first byte checked; the transfer; the read buffers
   copied back (EFAULT if any fails, the others still copied). The messages' copies are one
   process_vm_readv, the read buffers' one process_vm_writev. */
#define RECV_SLOT (1 + I2C_SMBUS_BLOCK_MAX + 1) /* a RECV_LEN message's count byte and data, and a spare */
static unsigned char junk[MAX_XFER]; /* where the bytes copied in only to check them go */

static int i2c_rdwr(struct fake *f, unsigned long uarg)
{
    struct i2c_rdwr_ioctl_data arg;
    if (copy_in(&arg, (void *)uarg, sizeof arg))
        return errno_ret(EFAULT);
    if (!arg.msgs || arg.nmsgs == 0 || arg.nmsgs > I2C_RDWR_IOCTL_MAX_MSGS)
        return errno_ret(EINVAL); /* a NULL msgs is EINVAL since Linux 5.11 */
    unsigned n = arg.nmsgs;
    struct i2c_msg user[I2C_RDWR_IOCTL_MAX_MSGS], k[I2C_RDWR_IOCTL_MAX_MSGS];
    if (copy_in(user, arg.msgs, n * sizeof *user))
        return errno_ret(EFAULT);
    unsigned too_long = 0; /* the first message above i2c-dev's limit: nothing from it on is copied */
    size_t wlen = 0, rlen = 0;
    while (too_long < n && user[too_long].len <= MAX_XFER) {
        const struct i2c_msg *m = &user[too_long++];
        if (!(m->flags & I2C_M_RD))
            wlen += m->len;
        else
            rlen += (m->flags & I2C_M_RECV_LEN) ? RECV_SLOT : m->len;
    }
    if (wlen > 2 * MAX_XFER || rlen > 2 * MAX_XFER)
        return errno_ret(EINVAL); /* more than one request to the session carries (the shim's limit) */
    static __thread unsigned char kbuf[4 * MAX_XFER + I2C_RDWR_IOCTL_MAX_MSGS * RECV_SLOT];
    struct iovec local[2 * I2C_RDWR_IOCTL_MAX_MSGS], remote[I2C_RDWR_IOCTL_MAX_MSGS];
    size_t nl = 0, nr = 0, at = 0;
    for (unsigned i = 0; i < too_long; i++) {
        k[i] = user[i];
        k[i].buf = kbuf + at;
        int recv = (user[i].flags & (I2C_M_RD | I2C_M_RECV_LEN)) == (I2C_M_RD | I2C_M_RECV_LEN);
        at += recv ? RECV_SLOT : user[i].len;
        if (!user[i].len)
            continue;
        remote[nr++] = (struct iovec){user[i].buf, user[i].len};
        local[nl++] = (struct iovec){k[i].buf, recv ? 1 : user[i].len};
        if (recv && user[i].len > 1)
            local[nl++] = (struct iovec){junk, user[i].len - 1u};
    }
    size_t copied = user_copy(local, nl, remote, nr, 0); /* messages with a buffer copied whole */
    for (unsigned i = 0, with_buf = 0; i < n; i++) {
        if (i == too_long)
            return errno_ret(EINVAL);
        if (user[i].len && with_buf++ == copied)
            return errno_ret(EFAULT);
        if ((user[i].flags & I2C_M_RECV_LEN) &&
            (!(user[i].flags & I2C_M_RD) || user[i].len < 1 || k[i].buf[0] < 1 ||
             user[i].len < k[i].buf[0] + I2C_SMBUS_BLOCK_MAX))
            return errno_ret(EINVAL); /* i2c-dev's own check */
    }
    int err = i2c_transfer(f, k, n);
    if (err)
        return errno_ret(err);
    nr = 0;
    for (unsigned i = 0; i < n; i++)
        if ((k[i].flags & I2C_M_RD) && k[i].len) {
            local[nr] = (struct iovec){k[i].buf, k[i].len};
            remote[nr++] = (struct iovec){user[i].buf, k[i].len};
        }
    for (size_t i = 0; i < nr; i++) { /* every buffer is tried, as i2c-dev does */
        i += user_copy(local + i, nr - i, remote + i, nr - i, 1);
        if (i < nr)
            err = EFAULT;
    }
    return err ? errno_ret(err) : (int)n;
}

/* SMBus over plain I2C messages, as the kernel's i2c_smbus_xfer_emulated does it, on a copy of the
   caller's data: copied in when i2c-dev copies it (a write, a process call, an I2C block), copied back
   (the whole size of its kind) after a read or a process call. */
static int i2c_smbus(struct fake *f, unsigned long uarg)
{
    struct i2c_smbus_ioctl_data arg, *a = &arg;
    if (copy_in(&arg, (void *)uarg, sizeof arg))
        return errno_ret(EFAULT);
    uint32_t size = a->size;
    int rd = a->read_write == I2C_SMBUS_READ;
    if (a->read_write != I2C_SMBUS_READ && a->read_write != I2C_SMBUS_WRITE)
        return errno_ret(EINVAL);
    if (size > I2C_SMBUS_I2C_BLOCK_DATA)
        return errno_ret(EINVAL);
    union i2c_smbus_data data = {0}, *d = NULL;
    size_t datasize = size == I2C_SMBUS_BYTE || size == I2C_SMBUS_BYTE_DATA ? sizeof data.byte
                      : size == I2C_SMBUS_WORD_DATA || size == I2C_SMBUS_PROC_CALL ? sizeof data.word
                                                                                  : sizeof data.block;
    int out = size == I2C_SMBUS_PROC_CALL || size == I2C_SMBUS_BLOCK_PROC_CALL || rd;
    if (!(size == I2C_SMBUS_QUICK || (size == I2C_SMBUS_BYTE && !rd))) {
        if (!a->data)
            return errno_ret(EINVAL);
        d = &data;
        if ((size == I2C_SMBUS_PROC_CALL || size == I2C_SMBUS_BLOCK_PROC_CALL || size == I2C_SMBUS_I2C_BLOCK_DATA ||
             !rd) &&
            copy_in(d, a->data, datasize))
            return errno_ret(EFAULT);
    }
    if (size == I2C_SMBUS_I2C_BLOCK_BROKEN) {
        size = I2C_SMBUS_I2C_BLOCK_DATA;
        if (rd)
            d->block[0] = I2C_SMBUS_BLOCK_MAX;
    }
    if (size == I2C_SMBUS_PROC_CALL || size == I2C_SMBUS_BLOCK_PROC_CALL)
        rd = 1; /* write then read, whatever read_write says */
    uint16_t addr = (uint16_t)f->addr, ten = f->tenbit ? I2C_M_TEN : 0;
    unsigned char w[2 + I2C_SMBUS_BLOCK_MAX + 1], r[1 + I2C_SMBUS_BLOCK_MAX + 1];
    struct i2c_msg m[2] = {{addr, ten, 1, w}, {addr, (uint16_t)(ten | I2C_M_RD), 0, r}};
    unsigned n = 2;
    w[0] = a->command;
    unsigned blk = d ? d->block[0] : 0;
    switch (size) {
    case I2C_SMBUS_QUICK:
        m[0].flags |= rd ? I2C_M_RD : 0;
        m[0].len = 0;
        n = 1;
        break;
    case I2C_SMBUS_BYTE:
        if (rd) {
            m[0] = m[1];
            m[0].len = 1;
        }
        n = 1;
        break;
    case I2C_SMBUS_BYTE_DATA:
        if (rd)
            m[1].len = 1;
        else {
            w[1] = d->byte;
            m[0].len = 2;
            n = 1;
        }
        break;
    case I2C_SMBUS_WORD_DATA:
    case I2C_SMBUS_PROC_CALL:
        if (size == I2C_SMBUS_PROC_CALL || !rd) {
            w[1] = (unsigned char)(d->word & 0xff);
            w[2] = (unsigned char)(d->word >> 8);
            m[0].len = 3;
        }
        if (rd)
            m[1].len = 2;
        else
            n = 1;
        break;
    case I2C_SMBUS_BLOCK_DATA:
    case I2C_SMBUS_BLOCK_PROC_CALL:
        if (size == I2C_SMBUS_BLOCK_PROC_CALL || !rd) {
            if (blk < 1 || blk > I2C_SMBUS_BLOCK_MAX)
                return errno_ret(EINVAL);
            memcpy(w + 1, d->block, blk + 1);
            m[0].len = (uint16_t)(blk + 2);
        }
        if (rd) {
            m[1].flags |= I2C_M_RECV_LEN;
            m[1].len = 1 + I2C_SMBUS_BLOCK_MAX;
            r[0] = 1;
        } else
            n = 1;
        break;
    case I2C_SMBUS_I2C_BLOCK_DATA:
        if (blk < 1 || blk > I2C_SMBUS_BLOCK_MAX)
            return errno_ret(EINVAL);
        if (rd)
            m[1].len = (uint16_t)blk;
        else {
            memcpy(w + 1, d->block + 1, blk);
            m[0].len = (uint16_t)(blk + 1);
            n = 1;
        }
        break;
    default:
        return errno_ret(EINVAL);
    }
    int err = i2c_transfer(f, m, n);
    if (err)
        return errno_ret(err);
    if (!d || !out)
        return 0;
    switch (size) {
    case I2C_SMBUS_BYTE:
        d->byte = r[0];
        break;
    case I2C_SMBUS_BYTE_DATA:
        d->byte = r[0];
        break;
    case I2C_SMBUS_WORD_DATA:
    case I2C_SMBUS_PROC_CALL:
        d->word = (uint16_t)(r[0] | r[1] << 8);
        break;
    case I2C_SMBUS_BLOCK_DATA:
    case I2C_SMBUS_BLOCK_PROC_CALL:
        memcpy(d->block, r, 1u + r[0]);
        break;
    case I2C_SMBUS_I2C_BLOCK_DATA:
        memcpy(d->block + 1, r, blk);
        break;
    }
    return copy_out(a->data, d, datasize) ? errno_ret(EFAULT) : 0;
}

static int i2c_ioctl(struct fake *f, unsigned long req, unsigned long arg)
{
    switch (req) {
    case I2C_SLAVE:
    case I2C_SLAVE_FORCE:
        if (arg > 0x3ff || (!f->tenbit && arg > 0x7f))
            return errno_ret(EINVAL);
        f->addr = (int)arg;
        return 0;
    case I2C_TENBIT:
        f->tenbit = arg != 0;
        return 0;
    case I2C_PEC:
        if (arg) {
            note("I2C_PEC: packet error checking is not emulated (I2C_FUNCS does not offer it)");
            return errno_ret(EINVAL);
        }
        return 0;
    case I2C_RETRIES:
    case I2C_TIMEOUT:
        return 0;
    case I2C_FUNCS: {
        unsigned long funcs = I2C_FUNC_I2C | (I2C_FUNC_SMBUS_EMUL_ALL & ~(unsigned long)I2C_FUNC_SMBUS_PEC);
        return copy_out((void *)arg, &funcs, sizeof funcs) ? errno_ret(EFAULT) : 0;
    }
    case I2C_RDWR:
        return i2c_rdwr(f, arg);
    case I2C_SMBUS:
        return i2c_smbus(f, arg);
    default:
        note("ioctl 0x%lx on /dev/i2c-%d is not an i2c-dev request (ENOTTY)", req, f->t.bus);
        return errno_ret(ENOTTY);
    }
}

EXPORT int ioctl(int fd, unsigned long req, ...)
{
    va_list ap;
    va_start(ap, req);
    unsigned long arg = va_arg(ap, unsigned long);
    va_end(ap);
    struct fake *f = fake_of(fd);
    if (f && f->t.kind == K_I2C)
        return i2c_ioctl(f, req, arg);
    if (f)
        return errno_ret(ENOTTY);
    catch_up(); /* FIONREAD on a pty looks at the outside world too */
    return LOAD(ioctl)(fd, req, arg);
}

/* ---------------------------------------------------------------- PWM attributes */

static int parse_u64(const char *buf, size_t n, uint64_t *out)
{
    char s[32];
    if (n == 0 || n >= sizeof s)
        return -1;
    memcpy(s, buf, n);
    s[n] = 0;
    if (s[n - 1] == '\n')
        s[--n] = 0; /* sysfs accepts one trailing newline, as echo writes */
    if (n == 0 || s[0] == '-' || s[0] == '+' || s[0] == ' ')
        return -1;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 0);
    if (errno || *end)
        return -1;
    *out = v;
    return 0;
}

static int streq_nl(const char *buf, size_t n, const char *word)
{
    size_t w = strlen(word);
    return (n == w || (n == w + 1 && buf[w] == '\n')) && memcmp(buf, word, w) == 0;
}

/* i2c-dev's read() and write() move at most 8192 bytes; sysfs takes at most a page per write, copied
   in before the attribute looks at it. The caller's buffer is copied as the kernel copies it. */
#define SYSFS_PAGE 4096
static __thread unsigned char xfer_buf[SYSFS_PAGE > MAX_XFER ? SYSFS_PAGE : MAX_XFER];

static ssize_t fake_write(struct fake *f, const void *buf, size_t n)
{
    if (f->t.kind == K_I2C) {
        size_t k = n > MAX_XFER ? MAX_XFER : n;
        if (copy_in(xfer_buf, buf, k))
            return errno_ret(EFAULT);
        struct i2c_msg m = {(uint16_t)f->addr, (uint16_t)(f->tenbit ? I2C_M_TEN : 0), (uint16_t)k, xfer_buf};
        int err = i2c_transfer(f, &m, 1);
        return err ? errno_ret(err) : (ssize_t)k;
    }
    if (f->t.kind != K_PWM_ATTR)
        return errno_ret(EBADF);
    n = n > SYSFS_PAGE ? SYSFS_PAGE : n;
    if (copy_in(xfer_buf, buf, n))
        return errno_ret(EFAULT);
    const char *s = (const char *)xfer_buf;
    uint64_t v = 0;
    struct rig_pwm_msg msg = {.chip = (uint16_t)pwm_chip, .channel = (uint16_t)(f->t.channel < 0 ? 0 : f->t.channel)};
    pthread_mutex_lock(&lock);
    int err = 0;
    struct rig_pwm_state *p = f->t.channel >= 0 ? &shm->pwm[f->t.channel] : NULL;
    switch (f->t.attr) {
    case A_EXPORT:
    case A_UNEXPORT:
        if (parse_u64(s, n, &v) < 0 || v >= shm->npwm) {
            err = v >= shm->npwm ? ENODEV : EINVAL;
            break;
        }
        p = &shm->pwm[v];
        if (f->t.attr == A_EXPORT && p->exported)
            err = EBUSY;
        else if (f->t.attr == A_UNEXPORT && !p->exported)
            err = ENODEV;
        else if (f->t.attr == A_EXPORT)
            p->exported = 1;
        else
            *p = (struct rig_pwm_state){0}; /* unexport turns the output off */
        msg.channel = (uint16_t)v;
        msg.attr = f->t.attr == A_EXPORT ? RIG_PWM_EXPORT : RIG_PWM_UNEXPORT;
        break;
    case A_NPWM:
        err = EACCES;
        break;
    case A_PERIOD:
    case A_DUTY:
        if (!p->exported)
            err = ENODEV;
        else if (parse_u64(s, n, &v) < 0)
            err = EINVAL;
        else if (f->t.attr == A_PERIOD ? (v < p->duty_ns || (v == 0 && p->enabled)) : v > p->period_ns)
            err = EINVAL; /* pwm_apply_state: duty above period, or an enabled zero period */
        else if (f->t.attr == A_PERIOD)
            p->period_ns = v;
        else
            p->duty_ns = v;
        msg.attr = f->t.attr == A_PERIOD ? RIG_PWM_PERIOD : RIG_PWM_DUTY;
        break;
    case A_ENABLE:
        if (!p->exported)
            err = ENODEV;
        else if (parse_u64(s, n, &v) < 0 || v > 1)
            err = EINVAL;
        else if (v == 1 && p->period_ns == 0)
            err = EINVAL;
        else
            p->enabled = (uint32_t)v;
        msg.attr = RIG_PWM_ENABLE;
        break;
    case A_POLARITY:
        if (!p->exported)
            err = ENODEV;
        else if (streq_nl(s, n, "normal"))
            v = 0;
        else if (streq_nl(s, n, "inversed"))
            v = 1;
        else
            err = EINVAL;
        if (!err)
            p->inversed = (uint32_t)v;
        msg.attr = RIG_PWM_POLARITY;
        break;
    }
    msg.value = v;
    if (!err) {
        ensure_connected();
        send_msg(RIG_MSG_PWM, &msg, sizeof msg); /* a notice: the DUT never waits for it */
    }
    pthread_mutex_unlock(&lock);
    return err ? errno_ret(err) : (ssize_t)n;
}

static ssize_t fake_read(struct fake *f, void *buf, size_t n, off_t *pos)
{
    if (f->t.kind == K_I2C) {
        size_t k = n > MAX_XFER ? MAX_XFER : n;
        struct i2c_msg m = {(uint16_t)f->addr, (uint16_t)(I2C_M_RD | (f->tenbit ? I2C_M_TEN : 0)), (uint16_t)k,
                            xfer_buf};
        int err = i2c_transfer(f, &m, 1);
        if (!err && copy_out(buf, xfer_buf, k))
            err = EFAULT; /* after the transfer, as i2c-dev's copy_to_user */
        return err ? errno_ret(err) : (ssize_t)k;
    }
    if (f->t.kind == K_PWM_DIR)
        return errno_ret(EISDIR);
    if (f->t.kind != K_PWM_ATTR)
        return errno_ret(EBADF);
    char text[32];
    struct rig_pwm_state *p = f->t.channel >= 0 ? &shm->pwm[f->t.channel] : NULL;
    switch (f->t.attr) {
    case A_EXPORT:
    case A_UNEXPORT:
        return errno_ret(EIO);
    case A_NPWM:
        snprintf(text, sizeof text, "%u\n", shm->npwm);
        break;
    case A_PERIOD:
        snprintf(text, sizeof text, "%llu\n", (unsigned long long)p->period_ns);
        break;
    case A_DUTY:
        snprintf(text, sizeof text, "%llu\n", (unsigned long long)p->duty_ns);
        break;
    case A_ENABLE:
        snprintf(text, sizeof text, "%u\n", p->enabled);
        break;
    case A_POLARITY:
        snprintf(text, sizeof text, "%s\n", p->inversed ? "inversed" : "normal");
        break;
    }
    size_t len = strlen(text);
    if (*pos < 0 || (size_t)*pos >= len)
        return 0;
    size_t k = len - (size_t)*pos < n ? len - (size_t)*pos : n;
    if (copy_out(buf, text + *pos, k))
        return errno_ret(EFAULT);
    *pos += (off_t)k;
    return (ssize_t)k;
}

EXPORT ssize_t read(int fd, void *buf, size_t n)
{
    struct fake *f = fake_of(fd);
    if (f)
        return fake_read(f, buf, n, &f->pos);
    catch_up();
    return LOAD(read)(fd, buf, n);
}

EXPORT ssize_t write(int fd, const void *buf, size_t n)
{
    struct fake *f = fake_of(fd);
    return f ? fake_write(f, buf, n) : LOAD(write)(fd, buf, n);
}

typedef ssize_t (*pread_fn)(int, void *, size_t, off_t);

static ssize_t pread_via(int fd, void *buf, size_t n, off_t off, pread_fn real)
{
    struct fake *f = fake_of(fd);
    if (f) /* i2c-dev has no offsets */
        return f->t.kind == K_I2C ? errno_ret(ESPIPE) : fake_read(f, buf, n, &off);
    catch_up();
    return real(fd, buf, n, off);
}

EXPORT ssize_t pread(int fd, void *buf, size_t n, off_t off) { return pread_via(fd, buf, n, off, LOAD(pread)); }
EXPORT ssize_t pread64(int fd, void *buf, size_t n, off_t off) { return pread_via(fd, buf, n, off, LOAD(pread64)); }

EXPORT ssize_t pwrite(int fd, const void *buf, size_t n, off_t off)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(pwrite)(fd, buf, n, off);
    return f->t.kind == K_I2C ? errno_ret(ESPIPE) : fake_write(f, buf, n);
}

EXPORT ssize_t pwrite64(int fd, const void *buf, size_t n, off_t off)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(pwrite64)(fd, buf, n, off);
    return f->t.kind == K_I2C ? errno_ret(ESPIPE) : fake_write(f, buf, n);
}

static off_t fake_seek(struct fake *f, off_t off, int whence)
{
    if (f->t.kind == K_I2C)
        return errno_ret(ESPIPE);
    off_t base = whence == SEEK_SET ? 0 : whence == SEEK_CUR ? f->pos : -1;
    if (base < 0 || base + off < 0)
        return errno_ret(EINVAL);
    f->pos = base + off;
    return f->pos;
}

EXPORT off_t lseek(int fd, off_t off, int whence)
{
    struct fake *f = fake_of(fd);
    return f ? fake_seek(f, off, whence) : LOAD(lseek)(fd, off, whence);
}

EXPORT off_t lseek64(int fd, off_t off, int whence)
{
    struct fake *f = fake_of(fd);
    return f ? fake_seek(f, off, whence) : LOAD(lseek64)(fd, off, whence);
}
