/* A test harness for the bridge core (not part of any bridge): a HAL whose clock the script sets, and
   a script on stdin, one command a line; what the core does comes out on stdout, one line each.
   tests/bridge/test_core.py drives it. Commands:
     t US                          the clock
     rx HEX                        bytes from the host, then bridge_idle (as the firmware's main loop)
     rxq HEX                       bytes from the host, the frames up left queued
     poll                          bridge_poll
     start TNS ADDR READ | wr TNS BYTE | rd TNS | stop TNS      I2C target events (ADDR, BYTE hex);
                                   after nostretch a read's start prints its first byte as "rd HEX"
     unread                        the master's NACK: the byte read ahead given back (and, after
                                   nostretch, the ports preloaded again)
     xfer TNS ADDR WHEX NREAD      a transfer as a 400 kHz master makes it: START, address, the written
                                   bytes, a repeated START and NREAD reads (if any), STOP, each event at
                                   its bit time: "xfer ok HEX" or "xfer nack"
     edge CH LEVEL COUNT TUS       bridge_capture_edge
     status                        the STATUS values as one line
     sbus_limit N                  the SBUS UART takes at most N bytes a frame from now on
     pwm_init BITS HZ MINW MAXW MINPER STALE | pwm_edge CH LEVEL COUNT TUS | pwm_widths TUS
                                   a pwm_capture of its own: "pulse 0|1", "widths a b c d",
                                   and "pwm PULSES GLITCHES" after each
     sbus_encode C0 .. C15 FLAGS   "frame HEX"
     locks                         "locks N": how often the core took the lock so far
     nostretch                     from now on the HAL preloads (i2c_preload), as a target that does
                                   not stretch SCL: "pre PORT HEX" each time it takes a byte; xfer then
                                   reads its first byte from what the port held, and gives the ports
                                   back at the NACK (bridge_i2c_preload_all)
     busy PORT 0|1                 the port refuses preloads (its target is sending) or takes them
   After each command but `t` and `rxq` the tool flushes the frames queued up (bridge_flush), as the
   firmware's main loop does between its calls.
   Out, from the HAL: "up HEX" (a frame to the host), "sbus HEX" (what the UART took), "addr AA 0|1",
   "can III HEX" (a CAN frame: identifier, data). The HAL's lock is checked: a frame given to the link,
   or a command that returns, with the lock held prints "lock error ..." (the tests look for it).
   `bridge_tool SCRIPT OUT` reads the script from the file SCRIPT and writes to the file OUT instead: so
   it runs on a Cortex-M4 under QEMU with semihosting (tests/bridge/tools.py), where the files are the
   host's. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/bridge.h"

static uint64_t clock_us;
static size_t sbus_limit = SBUS_FRAME;
static unsigned lock_depth;
static unsigned long locks_taken;
static uint8_t txdr[BRIDGE_I2C_PORTS];  /* what each target port holds for the next read */
static int port_busy[BRIDGE_I2C_PORTS]; /* `busy` */
static int sending[BRIDGE_I2C_PORTS];   /* a read under way */

/* the target port an address is on (bridge.h BRIDGE_I2C_PORTS) */
static unsigned port_of(uint8_t addr) { return addr == 0x1E ? 1u : 0u; }

static int hal_preload(void *ctx, unsigned port, uint8_t byte)
{
    (void)ctx;
    if (port >= BRIDGE_I2C_PORTS || port_busy[port] || sending[port])
        return 0;
    txdr[port] = byte;
    printf("pre %u %02x\n", port, byte);
    return 1;
}

static uint32_t hal_lock(void *ctx)
{
    (void)ctx;
    locks_taken++;
    return lock_depth++;
}

static void hal_unlock(void *ctx, uint32_t saved)
{
    (void)ctx;
    if (lock_depth == 0 || saved != lock_depth - 1)
        printf("lock error: unlock %lu at depth %u\n", (unsigned long)saved, lock_depth);
    lock_depth = saved;
}

static void hex(const char *tag, const uint8_t *p, size_t n)
{
    printf("%s ", tag);
    for (size_t i = 0; i < n; i++)
        printf("%02x", p[i]);
    printf("\n");
}

static uint64_t hal_now(void *ctx)
{
    (void)ctx;
    return clock_us;
}

static void hal_addr(void *ctx, uint8_t addr, int on)
{
    (void)ctx;
    printf("addr %02x %d\n", addr, on);
}

static void hal_link(void *ctx, const uint8_t *p, size_t n)
{
    (void)ctx;
    if (lock_depth)
        printf("lock error: a frame framed with the lock held\n");
    hex("up", p, n);
}

static size_t hal_sbus(void *ctx, const uint8_t *p, size_t n)
{
    (void)ctx;
    size_t k = n < sbus_limit ? n : sbus_limit;
    hex("sbus", p, k);
    return k;
}

static int hal_can(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    printf("can %03lx", (unsigned long)id);
    hex("", data, len);
    return 0;
}

static size_t unhex(const char *s, uint8_t *out, size_t cap)
{
    size_t n = 0;
    while (s[0] && s[1] && n < cap) {
        char two[3] = { s[0], s[1], 0 };
        out[n++] = (uint8_t)strtoul(two, NULL, 16);
        s += 2;
    }
    return n;
}

#define BIT_NS 2500u /* 400 kHz */

static void xfer(struct bridge *b, uint64_t t, uint8_t addr, const uint8_t *w, size_t nw, unsigned nr)
{
    uint8_t got[64];
    int ok = 1;
    t += BIT_NS; /* START */
    if (nw || !nr) {
        ok = bridge_i2c_start(b, t, addr, 0);
        t += 9 * BIT_NS;
        for (size_t i = 0; ok && i < nw; i++, t += 9 * BIT_NS)
            ok = bridge_i2c_write(b, t, w[i]);
    }
    if (ok && nr) {
        unsigned port = port_of(addr), i = 0;
        int preloaded = b->hal.i2c_preload != NULL;
        if (preloaded) { /* the first byte goes out from the port's register as the address is ACKed */
            sending[port] = 1;
            got[i++] = txdr[port];
        }
        ok = bridge_i2c_start(b, t, addr, 1);
        t += 10 * BIT_NS;
        for (; ok && i < nr && i < sizeof got; i++, t += 9 * BIT_NS)
            got[i] = bridge_i2c_read(b, t);
        if (ok) { /* as the STM32 target does: one byte loaded ahead, given back at the NACK */
            (void)bridge_i2c_read(b, t);
            bridge_i2c_unread(b);
        }
        sending[port] = 0;
        if (preloaded)
            bridge_i2c_preload_all(b);
    }
    bridge_i2c_stop(b, t);
    if (ok)
        hex("xfer ok", got, nr);
    else
        printf("xfer nack\n");
}

int main(int argc, char **argv)
{
    if (argc == 3 && (!freopen(argv[1], "r", stdin) || !freopen(argv[2], "w", stdout))) {
        fprintf(stderr, "bridge_tool: cannot open %s or %s\n", argv[1], argv[2]);
        return 2;
    }
    if (argc != 1 && argc != 3) {
        fprintf(stderr, "usage: bridge_tool [SCRIPT OUT]\n");
        return 2;
    }
    static char line[1 << 20];
    static uint8_t bytes[1 << 19];
    struct bridge_hal hal = { .now_us = hal_now,
                              .i2c_addr_enable = hal_addr,
                              .link_tx = hal_link,
                              .sbus_tx = hal_sbus,
                              .can_tx = hal_can,
                              .lock = hal_lock,
                              .unlock = hal_unlock };
    struct bridge_cfg cfg = bridge_defaults();
    memcpy(cfg.id, "bridge_tool", 11);
    static struct bridge b;
    bridge_init(&b, &hal, &cfg);
    struct pwm_capture pc;
    struct pwm_capture_cfg pcfg = pwm_capture_defaults();
    pwm_capture_init(&pc, &pcfg);
    while (fgets(line, sizeof line, stdin)) {
        char cmd[32] = "";
        unsigned long long a = 0, c = 0, d = 0, e = 0, f = 0, g = 0;
        char s1[1 << 10];
        int off = 0;
        if (sscanf(line, "%31s%n", cmd, &off) != 1)
            continue;
        const char *rest = line + off;
        if (!strcmp(cmd, "t")) {
            sscanf(rest, "%llu", &a);
            clock_us = a;
        } else if (!strcmp(cmd, "rx") || !strcmp(cmd, "rxq")) {
            while (*rest == ' ')
                rest++;
            size_t n = unhex(rest, bytes, sizeof bytes);
            bridge_link_rx(&b, bytes, n);
            if (!strcmp(cmd, "rx"))
                bridge_idle(&b); /* as the firmware's main loop after a chunk: its samples encoded ahead */
        } else if (!strcmp(cmd, "poll")) {
            bridge_poll(&b);
        } else if (!strcmp(cmd, "idle")) {
            bridge_idle(&b);
        } else if (!strcmp(cmd, "start")) {
            sscanf(rest, "%llu %llx %llu", &a, &c, &d);
            unsigned port = port_of((uint8_t)c);
            if (d && b.hal.i2c_preload) { /* the byte the port held goes out first */
                sending[port] = 1;
                printf("rd %02x\n", txdr[port]);
            }
            printf("ack %d\n", bridge_i2c_start(&b, a, (uint8_t)c, (int)d));
        } else if (!strcmp(cmd, "wr")) {
            sscanf(rest, "%llu %llx", &a, &c);
            printf("ack %d\n", bridge_i2c_write(&b, a, (uint8_t)c));
        } else if (!strcmp(cmd, "rd")) {
            sscanf(rest, "%llu", &a);
            printf("rd %02x\n", bridge_i2c_read(&b, a));
        } else if (!strcmp(cmd, "unread")) { /* the master's NACK: the byte read ahead given back */
            bridge_i2c_unread(&b);
            memset(sending, 0, sizeof sending);
            if (b.hal.i2c_preload)
                bridge_i2c_preload_all(&b);
        } else if (!strcmp(cmd, "stop")) {
            sscanf(rest, "%llu", &a);
            memset(sending, 0, sizeof sending);
            bridge_i2c_stop(&b, a);
        } else if (!strcmp(cmd, "xfer")) {
            s1[0] = 0;
            sscanf(rest, "%llu %llx %1023s %llu", &a, &c, s1, &d);
            size_t nw = strcmp(s1, "-") ? unhex(s1, bytes, 64) : 0;
            xfer(&b, a, (uint8_t)c, bytes, nw, (unsigned)d);
        } else if (!strcmp(cmd, "edge")) {
            sscanf(rest, "%llu %llu %llu %llu", &a, &c, &d, &e);
            bridge_capture_edge(&b, (unsigned)a, (int)c, (uint32_t)d, e);
        } else if (!strcmp(cmd, "status")) {
            struct bridge_status st;
            bridge_status(&b, &st);
            printf("status underruns %lu %lu %lu late %lu i2c_errors %lu ok %lu bad %lu gaps %lu refused %lu "
                   "glitches %lu sbus_dropped %lu silent %u agreed %d preload_misses %lu\n",
                   (unsigned long)st.underruns[0], (unsigned long)st.underruns[1], (unsigned long)st.underruns[2],
                   (unsigned long)st.late_samples, (unsigned long)st.i2c_errors, (unsigned long)st.frames_ok,
                   (unsigned long)st.frames_bad, (unsigned long)st.seq_gaps, (unsigned long)st.refused,
                   (unsigned long)st.pulse_glitches, (unsigned long)st.sbus_dropped, (unsigned)st.host_silent, b.agreed,
                   (unsigned long)st.i2c_preload_misses);
        } else if (!strcmp(cmd, "nostretch")) {
            b.hal.i2c_preload = hal_preload;
            bridge_i2c_preload_all(&b);
        } else if (!strcmp(cmd, "busy")) {
            sscanf(rest, "%llu %llu", &a, &c);
            if (a < BRIDGE_I2C_PORTS)
                port_busy[a] = (int)c;
        } else if (!strcmp(cmd, "locks")) {
            printf("locks %lu\n", locks_taken);
        } else if (!strcmp(cmd, "sbus_limit")) {
            sscanf(rest, "%llu", &a);
            sbus_limit = (size_t)a;
        } else if (!strcmp(cmd, "pwm_init")) {
            sscanf(rest, "%llu %llu %llu %llu %llu %llu", &a, &c, &d, &e, &f, &g);
            struct pwm_capture_cfg k = { (uint8_t)a, (uint32_t)c, (uint32_t)d, (uint32_t)e, (uint32_t)f, (uint32_t)g };
            pwm_capture_init(&pc, &k);
        } else if (!strcmp(cmd, "pwm_edge")) {
            sscanf(rest, "%llu %llu %llu %llu", &a, &c, &d, &e);
            printf("pulse %d\n", pwm_capture_edge(&pc, (unsigned)a, (int)c, (uint32_t)d, e));
            printf("pwm %lu %lu\n", (unsigned long)pc.pulses, (unsigned long)pc.glitches);
        } else if (!strcmp(cmd, "pwm_widths")) {
            sscanf(rest, "%llu", &a);
            uint16_t w[PWM_CAPTURE_CHANNELS];
            pwm_capture_widths(&pc, a, w);
            printf("widths %u %u %u %u\n", w[0], w[1], w[2], w[3]);
        } else if (!strcmp(cmd, "sbus_encode")) {
            uint16_t ch[SBUS_CHANNELS];
            const char *p = rest;
            char *end;
            for (int i = 0; i < SBUS_CHANNELS; i++, p = end)
                ch[i] = (uint16_t)strtoul(p, &end, 10);
            uint8_t frame[SBUS_FRAME];
            sbus_encode(ch, (uint8_t)strtoul(p, NULL, 10), frame);
            hex("frame", frame, SBUS_FRAME);
        } else {
            fprintf(stderr, "bridge_tool: unknown command %s\n", cmd);
            return 2;
        }
        if (lock_depth)
            printf("lock error: %s returned with the lock held\n", cmd);
        if (strcmp(cmd, "t") && strcmp(cmd, "rxq"))
            bridge_flush(&b);
        fflush(stdout);
    }
    return 0;
}
