/* The virtual bridge's board side (docs/design.md §8): the DUT's shim connections, its I2C transfers
   played to the core as the target events of a 400 kHz bus, its sysfs PWM writes as captured edges. */
#include "vbridge.h"

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
void pwm_edges(uint64_t now)
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

uint64_t pwm_next(void)
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

void drop(struct conn *c)
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

void on_readable(struct conn *c)
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

void send_due_replies(uint64_t now)
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
