/* The virtual bridge (docs/design.md §8): the bridge core as a Linux process on the wall clock
   (CLOCK_MONOTONIC microseconds). Its host link is a pty it opens itself; its board is a Linux-process
   DUT under the rig's shim (rig/shim/protocol.h, real time: RIG_LOCKSTEP=0), whose I2C transfers it
   plays to the core as the target events of a 400 kHz bus, whose sysfs PWM writes become captured
   edges, and whose RC serial port gets the SBUS frames.

   At start it prints one line on stdout and then serves:
     vbridge link=PTY board=SOCKET shm=PAGE rc=PTY fakes=DIR pid=PID
   link: the host opens it as a bridge's serial port; board, shm, fakes: RIG_SOCKET, RIG_SHM, RIG_FAKES
   of the DUT; rc: the pty whose other end is the board's RC input (RIG_SERIAL=/dev/ttyRC0=<rc>).

   It never blocks on the host: frames up go through a buffer that drops whole frames when full
   (counted); SBUS bytes the RC pty cannot take are dropped and counted by the core. It ends on SIGTERM,
   SIGINT, or the host closing its link (after it had opened it), removing its folder. Options:
     --bus N           the emulated bus /dev/i2c-N (1)
     --pwm-channels N  channels of pwmchip0 (8); the first four are captured
     --id NAME         the bridge's name in HELLO_REPLY (vbridge)
   This file is the set-up, the HAL and the loop; vbridge_board.c is the board's side. */
#include "vbridge.h"

static volatile sig_atomic_t stop_signal;
static void on_signal(int sig) { stop_signal = sig; }

static char dir[64], sock_path[128], shm_path[128], fakes_path[128];

struct vbridge_state v;

uint64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

/* ---------------------------------------------------------------- the HAL */

static uint64_t hal_now(void *ctx)
{
    (void)ctx;
    return mono_ns() / 1000u;
}

static void hal_addr(void *ctx, uint8_t addr, int on)
{
    (void)ctx;
    (void)addr;
    (void)on; /* a Linux bus has no target hardware to program: the core NACKs what it does not answer */
}

static void flush_tx(void)
{
    while (v.tx_n) {
        ssize_t k = write(v.link, v.tx, v.tx_n);
        if (k <= 0)
            return; /* EAGAIN, or no host yet: kept for later */
        memmove(v.tx, v.tx + k, v.tx_n - (size_t)k);
        v.tx_n -= (size_t)k;
    }
}

static void hal_link(void *ctx, const uint8_t *p, size_t n)
{
    (void)ctx;
    if (v.tx_n + n > sizeof v.tx) {
        v.tx_dropped++; /* whole frames only: the host sees a gap in the sequence */
        return;
    }
    memcpy(v.tx + v.tx_n, p, n);
    v.tx_n += n;
    flush_tx();
}

static size_t hal_sbus(void *ctx, const uint8_t *p, size_t n)
{
    (void)ctx;
    ssize_t k = write(v.rc, p, n);
    return k > 0 ? (size_t)k : 0;
}

/* One capture frame as an slcan adapter hands it to its host: "tIIILDD..\r" (python-can's slcan reads
   it). A full pty drops the frame (the core counts it; the host sees a gap in the sequence byte). */
static int hal_can(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    char line[32];
    int n = snprintf(line, sizeof line, "t%03X%u", (unsigned)(id & 0x7FFu), (unsigned)(len & 0x0Fu));
    for (uint8_t i = 0; i < len && i < 8; i++)
        n += snprintf(line + n, sizeof line - (size_t)n, "%02X", data[i]);
    line[n++] = '\r';
    return write(v.can, line, (size_t)n) == n ? 0 : -1;
}

/* What the adapter's host says (python-can's "O", "C", "S6"...) is read and let go: nothing to act on. */
static void drain_can(uint64_t now)
{
    if (now < v.can_drain_ns)
        return;
    v.can_drain_ns = now + 10000000u;
    char buf[256];
    while (read(v.can, buf, sizeof buf) > 0) {
    }
}

/* ---------------------------------------------------------------- set-up and the loop */

static void cleanup(void)
{
    if (!dir[0])
        return;
    unlink(sock_path);
    unlink(shm_path);
    DIR *d = opendir(fakes_path); /* the shim's backing files, one per emulated descriptor */
    if (d) {
        struct dirent *e;
        while ((e = readdir(d)) != NULL)
            if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
                unlinkat(dirfd(d), e->d_name, 0);
        closedir(d);
    }
    rmdir(fakes_path);
    if (rmdir(dir) < 0)
        fprintf(stderr, "vbridge: could not remove %s: %s\n", dir, strerror(errno));
    dir[0] = 0;
}

static int open_pty(char *name, size_t n, int raw_now)
{
    int m = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (m < 0 || grantpt(m) < 0 || unlockpt(m) < 0 || ptsname_r(m, name, n) != 0)
        return -1;
    int s = open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (s < 0)
        return -1;
    struct termios t;
    if (tcgetattr(s, &t) == 0) {
        cfmakeraw(&t);
        tcsetattr(s, TCSANOW, &t);
    }
    if (!raw_now) {
        close(s);
        return m;
    }
    v.rc_slave = s; /* kept open: the RC line is always there, like the session's ptys */
    return m;
}

static int make_shm(void)
{
    int fd = open(shm_path, O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0 || ftruncate(fd, 4096) < 0)
        return -1;
    struct rig_shm s;
    memset(&s, 0, sizeof s);
    s.magic = RIG_SHM_MAGIC;
    s.version = RIG_PROTOCOL_VERSION;
    s.npwm = v.npwm;
    s.limit_ns = UINT64_MAX;
    int e = pwrite(fd, &s, sizeof s, 0) == (ssize_t)sizeof s ? 0 : -1;
    close(fd);
    return e;
}

static int make_listener(void)
{
    int s = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    struct sockaddr_un a = { .sun_family = AF_UNIX };
    if (s < 0 || strlen(sock_path) >= sizeof a.sun_path)
        return -1;
    strcpy(a.sun_path, sock_path);
    if (bind(s, (struct sockaddr *)&a, sizeof a) < 0 || listen(s, 16) < 0)
        return -1;
    return s;
}

static void accept_conns(void)
{
    for (;;) {
        int fd = accept4(v.listener, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (fd < 0)
            return;
        int slot = -1;
        for (int i = 0; i < MAX_CONNS && slot < 0; i++)
            if (v.conns[i].fd < 0)
                slot = i;
        if (slot < 0) {
            fprintf(stderr, "vbridge: more than %d DUT connections: one refused\n", MAX_CONNS);
            close(fd);
            continue;
        }
        v.conns[slot].fd = fd;
    }
}

static int fail(const char *what)
{
    fprintf(stderr, "vbridge: %s: %s\n", what, strerror(errno));
    cleanup();
    return 1;
}

int main(int argc, char **argv)
{
    struct bridge_cfg cfg = bridge_defaults();
    memset(cfg.id, 0, sizeof cfg.id);
    memcpy(cfg.id, "vbridge", 7);
    cfg.clock_hz = 1000000u;
    v.bus = 1;
    v.npwm = 8;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--bus") && i + 1 < argc)
            v.bus = (unsigned)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--pwm-channels") && i + 1 < argc)
            v.npwm = (unsigned)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--id") && i + 1 < argc) {
            size_t k = strlen(argv[++i]);
            memset(cfg.id, 0, sizeof cfg.id);
            memcpy(cfg.id, argv[i], k < sizeof cfg.id ? k : sizeof cfg.id);
        } else {
            fprintf(stderr, "usage: vbridge [--bus N] [--pwm-channels N] [--id NAME]\n");
            return 2;
        }
    }
    if (v.npwm < 1 || v.npwm > RIG_PWM_MAX || v.bus > 31) {
        fprintf(stderr, "vbridge: --pwm-channels is 1..%d, --bus 0..31\n", RIG_PWM_MAX);
        return 2;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    /* its wake-ups (replies due, PWM edges) on time: a normal thread's may be deferred by a 50 us timer
       slack (none under SCHED_RR, which the host gives it where permitted: rig/bridge/session.py) */
    prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
    for (int i = 0; i < MAX_CONNS; i++)
        v.conns[i].fd = -1;

    const char *tmp = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/vbridge.XXXXXX", tmp && strlen(tmp) < 40 ? tmp : "/tmp");
    if (!mkdtemp(dir)) {
        dir[0] = 0;
        return fail("mkdtemp");
    }
    snprintf(sock_path, sizeof sock_path, "%s/board.sock", dir);
    snprintf(shm_path, sizeof shm_path, "%s/shm", dir);
    snprintf(fakes_path, sizeof fakes_path, "%s/fakes", dir);
    char link_name[64], rc_name[64], can_name[64];
    if (mkdir(fakes_path, 0700) < 0 || make_shm() < 0)
        return fail("the shared page");
    if ((v.listener = make_listener()) < 0)
        return fail("the board socket");
    if ((v.link = open_pty(link_name, sizeof link_name, 0)) < 0 || (v.rc = open_pty(rc_name, sizeof rc_name, 1)) < 0 ||
        (v.can = open_pty(can_name, sizeof can_name, 0)) < 0)
        return fail("a pty");

    /* one thread, no interrupts: no lock; its board's transfers come whole, so it needs no preloading */
    struct bridge_hal hal = {
        .now_us = hal_now, .i2c_addr_enable = hal_addr, .link_tx = hal_link, .sbus_tx = hal_sbus, .can_tx = hal_can
    };
    bridge_init(&v.b, &hal, &cfg);
    printf("vbridge link=%s board=%s shm=%s rc=%s can=%s fakes=%s pid=%d\n", link_name, sock_path, shm_path, rc_name,
           can_name, fakes_path, (int)getpid());
    fflush(stdout);

    struct pollfd pf[MAX_CONNS + 2];
    int why = 0;
    while (!stop_signal) {
        uint64_t now = mono_ns();
        pwm_edges(now);
        send_due_replies(now);
        bridge_poll(&v.b);
        bridge_idle(&v.b); /* as the firmware's main loop: the next samples encoded ahead */
        drain_can(now);
        int n = 0;
        pf[n++] = (struct pollfd){ v.listener, POLLIN, 0 };
        /* the link: watched once the host has it open (a pty with no slave open reports a hang-up) */
        pf[n++] = (struct pollfd){ v.link, (short)(POLLIN | (v.tx_n ? POLLOUT : 0)), 0 };
        int idx[MAX_CONNS];
        for (int i = 0; i < MAX_CONNS; i++)
            if (v.conns[i].fd >= 0 && !v.conns[i].pending) {
                idx[n - 2] = i;
                pf[n++] = (struct pollfd){ v.conns[i].fd, POLLIN, 0 };
            }
        uint64_t next = now + 1000000u; /* bridge_poll at least every ms */
        uint64_t t = pwm_next();
        if (t < next)
            next = t;
        for (int i = 0; i < MAX_CONNS; i++)
            if (v.conns[i].fd >= 0 && v.conns[i].pending && v.conns[i].due_ns < next)
                next = v.conns[i].due_ns;
        if (!v.host_seen) { /* no host yet: look at the link every ms, not on its hang-up */
            pf[1].fd = -1;
            struct pollfd probe = { v.link, POLLIN, 0 };
            if (poll(&probe, 1, 0) >= 0 && !(probe.revents & POLLHUP))
                v.host_seen = 1;
        }
        struct timespec ts = { 0, next > now ? (long)(next - now) : 0 };
        int r = ppoll(pf, (nfds_t)n, &ts, NULL);
        if (r < 0 && errno != EINTR)
            return fail("poll");
        if (r <= 0)
            continue;
        if (pf[0].revents)
            accept_conns();
        if (pf[1].revents & POLLIN) {
            uint8_t buf[4096];
            ssize_t k = read(v.link, buf, sizeof buf);
            if (k > 0)
                bridge_link_rx(&v.b, buf, (size_t)k);
            else if (k < 0 && errno == EIO) {
                why = 1;
                break;
            }
        } else if (pf[1].revents & (POLLHUP | POLLERR)) {
            why = 1;
            break;
        }
        if (pf[1].revents & POLLOUT)
            flush_tx();
        for (int i = 2; i < n; i++)
            if (pf[i].revents)
                on_readable(&v.conns[idx[i - 2]]);
    }
    if (why)
        fprintf(stderr, "vbridge: the host closed the link; stopping\n");
    for (int i = 0; i < MAX_CONNS; i++)
        if (v.conns[i].fd >= 0)
            drop(&v.conns[i]);
    close(v.listener);
    cleanup();
    return 0;
}
