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
     --id NAME         the bridge's name in HELLO_REPLY (vbridge) */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "bridge.h"
#include "protocol.h"

#define MAX_CONNS 32
#define BIT_NS 2500u /* 400 kHz */
#define TX_BUF 65536
#define I2C_M_RD 0x0001
#define I2C_M_TEN 0x0010
#define I2C_M_RECV_LEN 0x0400
#define I2C_SMBUS_BLOCK_MAX 32

static volatile sig_atomic_t stop_signal;
static void on_signal(int sig) { stop_signal = sig; }

static char dir[64], sock_path[128], shm_path[128], fakes_path[128];

struct conn {
    int fd;
    int hello;
    uint8_t *buf; /* header + payload being received */
    size_t have, need;
    /* a reply held until the transfer's end on the wall clock */
    int pending;
    uint64_t due_ns;
    uint8_t *reply;
    size_t reply_len;
};

struct pwm_ch {
    uint64_t period_ns, duty_ns;
    int exported, enabled, inversed;
    uint64_t next_rise_ns; /* 0: no pulses */
    uint64_t fall_ns;      /* the fall of the pulse under way (0: low) */
};

static struct {
    struct bridge b;
    int link; /* the host link's pty master */
    int rc, rc_slave;
    int can; /* the CAN bus as an slcan adapter's pty (master) */
    uint64_t can_drain_ns;
    int listener;
    int host_seen; /* the host opened the link once */
    unsigned bus, npwm;
    struct conn conns[MAX_CONNS];
    struct pwm_ch pwm[RIG_PWM_MAX];
    uint8_t tx[TX_BUF];
    size_t tx_n;
    unsigned long tx_dropped;
} v;

static uint64_t mono_ns(void)
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

/* ---------------------------------------------------------------- the board's I2C */

static int i2c_status(uint8_t *in, size_t len, uint8_t *out, size_t *out_len, uint64_t *t_end)
{
    if (len < 4)
        return -1;
    uint16_t bus, n;
    memcpy(&bus, in, 2);
    memcpy(&n, in + 2, 2);
    if (n < 1 || n > 42 || len < 4 + (size_t)n * sizeof(struct rig_i2c_msg))
        return -1;
    struct rig_i2c_msg m[42];
    memcpy(m, in + 4, n * sizeof *m);
    size_t at = 4 + n * sizeof *m, o = 0;
    for (unsigned i = 0; i < n; i++) {
        if (m[i].len > 8192)
            return -1;
        if (!(m[i].flags & I2C_M_RD))
            at += m[i].len;
    }
    if (at != len)
        return -1;
    if (bus != v.bus)
        return ENODEV;
    uint64_t t = mono_ns() + BIT_NS; /* START */
    const uint8_t *w = in + 4 + n * sizeof *m;
    int status = 0;
    for (unsigned i = 0; i < n && !status; i++) {
        int rd = (m[i].flags & I2C_M_RD) != 0;
        uint8_t addr = m[i].addr <= 0x7F && !(m[i].flags & I2C_M_TEN) ? (uint8_t)m[i].addr : 0;
        if (i)
            t += BIT_NS; /* a repeated START */
        int ack = bridge_i2c_start(&v.b, t, addr, rd);
        t += 9 * BIT_NS;
        if (!ack) {
            status = ENXIO;
            break;
        }
        if (!rd) {
            for (unsigned k = 0; k < m[i].len; k++, t += 9 * BIT_NS)
                if (!bridge_i2c_write(&v.b, t, w[k])) {
                    status = ENXIO;
                    break;
                }
            w += m[i].len;
            continue;
        }
        unsigned count = m[i].len;
        if (m[i].flags & I2C_M_RECV_LEN) {
            uint8_t c = bridge_i2c_read(&v.b, t);
            t += 9 * BIT_NS;
            out[o++] = c;
            if (c == 0 || c > I2C_SMBUS_BLOCK_MAX) {
                status = EPROTO;
                break;
            }
            count = c;
        }
        for (unsigned k = 0; k < count; k++, t += 9 * BIT_NS)
            out[o++] = bridge_i2c_read(&v.b, t);
        (void)bridge_i2c_read(&v.b, t); /* as the STM32 target: one byte ahead, given back at the NACK */
        bridge_i2c_unread(&v.b);
    }
    bridge_i2c_stop(&v.b, t);
    t += BIT_NS;
    *out_len = status ? 0 : o;
    *t_end = t;
    return status;
}

/* ---------------------------------------------------------------- the board's PWM */

/* the channel's pulses from now on, as the DUT set them: the high time of an enabled channel */
static void pwm_restart(unsigned ch)
{
    struct pwm_ch *p = &v.pwm[ch];
    uint64_t high = p->inversed ? p->period_ns - (p->duty_ns < p->period_ns ? p->duty_ns : p->period_ns) : p->duty_ns;
    int on = p->exported && p->enabled && p->period_ns && high > 0 && high < p->period_ns;
    if (!on) {
        p->next_rise_ns = 0;
        p->fall_ns = 0;
        return;
    }
    if (!p->next_rise_ns && !p->fall_ns)
        p->next_rise_ns = mono_ns();
}

static uint32_t capture_count(uint64_t t_ns) { return (uint32_t)(t_ns / 100u); } /* a 10 MHz 32-bit timer */

/* every edge due by now, at its own time (a late loop catches up, skipping whole periods it missed) */
static void pwm_edges(uint64_t now)
{
    for (unsigned ch = 0; ch < PWM_CAPTURE_CHANNELS && ch < v.npwm; ch++) {
        struct pwm_ch *p = &v.pwm[ch];
        for (int guard = 0; guard < 4; guard++) {
            if (p->fall_ns && p->fall_ns <= now) {
                bridge_capture_edge(&v.b, ch, 0, capture_count(p->fall_ns), p->fall_ns / 1000u);
                p->fall_ns = 0;
            } else if (!p->fall_ns && p->next_rise_ns && p->next_rise_ns <= now) {
                uint64_t high = p->inversed ? p->period_ns - p->duty_ns : p->duty_ns;
                if (now - p->next_rise_ns > p->period_ns) /* behind: on from the latest rise */
                    p->next_rise_ns += (now - p->next_rise_ns) / p->period_ns * p->period_ns;
                bridge_capture_edge(&v.b, ch, 1, capture_count(p->next_rise_ns), p->next_rise_ns / 1000u);
                p->fall_ns = p->next_rise_ns + high;
                p->next_rise_ns += p->period_ns;
            } else {
                break;
            }
        }
    }
}

static uint64_t pwm_next(void)
{
    uint64_t next = UINT64_MAX;
    for (unsigned ch = 0; ch < PWM_CAPTURE_CHANNELS && ch < v.npwm; ch++) {
        const struct pwm_ch *p = &v.pwm[ch];
        uint64_t t = p->fall_ns ? p->fall_ns : p->next_rise_ns;
        if (t && t < next)
            next = t;
    }
    return next;
}

static int pwm_notice(const uint8_t *payload, size_t len)
{
    struct rig_pwm_msg m;
    if (len != sizeof m)
        return -1;
    memcpy(&m, payload, sizeof m);
    if (m.chip != 0 || m.channel >= v.npwm || m.attr < RIG_PWM_EXPORT || m.attr > RIG_PWM_POLARITY)
        return -1;
    struct pwm_ch *p = &v.pwm[m.channel];
    switch (m.attr) {
    case RIG_PWM_EXPORT:
        p->exported = 1;
        break;
    case RIG_PWM_UNEXPORT:
        memset(p, 0, sizeof *p);
        break;
    case RIG_PWM_PERIOD:
        p->period_ns = m.value;
        break;
    case RIG_PWM_DUTY:
        p->duty_ns = m.value;
        break;
    case RIG_PWM_ENABLE:
        p->enabled = m.value != 0;
        break;
    default:
        p->inversed = m.value != 0;
        break;
    }
    if (m.channel < PWM_CAPTURE_CHANNELS)
        pwm_restart(m.channel);
    return 0;
}

/* ---------------------------------------------------------------- the board's connections */

static void drop(struct conn *c)
{
    close(c->fd);
    free(c->buf);
    free(c->reply);
    memset(c, 0, sizeof *c);
    c->fd = -1;
}

static int send_all(int fd, const void *p, size_t n)
{
    const char *s = p;
    while (n) {
        ssize_t k = send(fd, s, n, MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0 && errno == EAGAIN) { /* the shim reads its reply at once; wait for room */
            struct pollfd pf = { fd, POLLOUT, 0 };
            if (poll(&pf, 1, 1000) <= 0)
                return -1;
            continue;
        }
        if (k <= 0)
            return -1;
        s += k;
        n -= (size_t)k;
    }
    return 0;
}

static int reply(struct conn *c, uint16_t type, uint16_t status, const uint8_t *payload, uint32_t len)
{
    struct rig_hdr h = { len, type, status, 0 };
    uint8_t *r = malloc(sizeof h + len);
    if (!r)
        return -1;
    memcpy(r, &h, sizeof h);
    if (len)
        memcpy(r + sizeof h, payload, len);
    int e = send_all(c->fd, r, sizeof h + len);
    free(r);
    return e;
}

/* one whole message from the DUT: -1 drops its connection (malformed) */
static int handle(struct conn *c)
{
    struct rig_hdr h;
    memcpy(&h, c->buf, sizeof h);
    uint8_t *p = c->buf + sizeof h;
    if (!c->hello && h.type != RIG_MSG_HELLO)
        return -1;
    switch (h.type) {
    case RIG_MSG_HELLO: {
        uint32_t hello[2];
        if (h.len != sizeof hello)
            return -1;
        memcpy(hello, p, sizeof hello);
        c->hello = 1;
        return reply(c, RIG_MSG_HELLO, hello[0] == RIG_PROTOCOL_VERSION ? 0 : EPROTO, NULL, 0);
    }
    case RIG_MSG_I2C: {
        static uint8_t out[2 * 8192 + 64];
        size_t n = 0;
        uint64_t end = 0;
        int status = i2c_status(p, h.len, out, &n, &end);
        if (status < 0)
            return -1;
        struct rig_hdr rh = { (uint32_t)n, RIG_MSG_I2C, (uint16_t)status, 0 };
        c->reply = malloc(sizeof rh + n);
        if (!c->reply)
            return -1;
        memcpy(c->reply, &rh, sizeof rh);
        memcpy(c->reply + sizeof rh, out, n);
        c->reply_len = sizeof rh + n;
        c->due_ns = end;
        c->pending = 1;
        return 0;
    }
    case RIG_MSG_PWM:
        return pwm_notice(p, h.len);
    case RIG_MSG_WAIT: {
        uint64_t wake;
        uint32_t kind;
        if (h.len != 16)
            return -1;
        memcpy(&wake, p, 8);
        memcpy(&kind, p + 8, 4);
        (void)wake;
        if (kind != RIG_WAIT_SLEEP && kind != RIG_WAIT_POLL)
            return -1; /* AHEAD is lockstep's */
        uint32_t why = RIG_WAKE_DEADLINE;
        return reply(c, RIG_MSG_WAIT, 0, (const uint8_t *)&why, sizeof why);
    }
    case RIG_MSG_NOTE:
        fprintf(stderr, "vbridge: note from the DUT: %.*s\n", (int)(h.len < 300 ? h.len : 300), (const char *)p);
        return 0;
    default:
        return -1;
    }
}

static void on_readable(struct conn *c)
{
    for (;;) {
        if (c->pending)
            return; /* one request at a time: the next is read once this reply went */
        if (!c->buf) {
            c->buf = malloc(sizeof(struct rig_hdr) + RIG_MAX_PAYLOAD);
            if (!c->buf) {
                drop(c);
                return;
            }
            c->have = 0;
            c->need = sizeof(struct rig_hdr);
        }
        ssize_t k = recv(c->fd, c->buf + c->have, c->need - c->have, MSG_DONTWAIT);
        if (k < 0 && (errno == EAGAIN || errno == EINTR))
            return;
        if (k <= 0) {
            drop(c);
            return;
        }
        c->have += (size_t)k;
        if (c->have < c->need)
            continue;
        if (c->need == sizeof(struct rig_hdr)) {
            struct rig_hdr h;
            memcpy(&h, c->buf, sizeof h);
            if (h.len > RIG_MAX_PAYLOAD) {
                drop(c);
                return;
            }
            c->need += h.len;
            if (h.len)
                continue;
        }
        int e = handle(c);
        c->have = 0;
        c->need = sizeof(struct rig_hdr);
        if (e < 0) {
            fprintf(stderr, "vbridge: a malformed message from the DUT: its connection dropped\n");
            drop(c);
            return;
        }
    }
}

static void send_due_replies(uint64_t now)
{
    for (int i = 0; i < MAX_CONNS; i++) {
        struct conn *c = &v.conns[i];
        if (c->fd < 0 || !c->pending || c->due_ns > now)
            continue;
        c->pending = 0;
        int e = send_all(c->fd, c->reply, c->reply_len);
        free(c->reply);
        c->reply = NULL;
        if (e < 0)
            drop(c);
        else
            on_readable(c); /* requests that came meanwhile */
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
