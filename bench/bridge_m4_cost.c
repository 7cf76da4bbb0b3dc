/* What the bridge core costs on a Cortex-M4, in instructions (not a test): run by
   bench/bridge_m4_cost.py under QEMU's mps2-an386 with -icount shift=0, where SysTick, clocked from
   the emulated 25 MHz, advances once per 40 instructions executed. The core and the real chip core
   (emulators/chips) serve a board reading its MPU-6050 as a flight controller does at 1 kHz: each
   millisecond the host's IMU sample arrives (bridge_link_rx), the main loop encodes it ahead
   (bridge_idle, interruptible), the port polls (bridge_poll), and the
   board reads ACCEL_XOUT_H..GYRO_ZOUT_L in one 14-byte burst with a repeated START, every event of it
   timed. Prints one line per kind of call: "NAME calls N mean_insns M max_insns X locked_max L", L
   the longest the call held the HAL's lock (interrupts masked on the firmware: how long an I2C event
   that arrives then waits). It serves the board twice: as a target that stretches SCL, then as one
   that does not (the firmware's NOSTRETCH: i2c_preload, each read's first byte taken at its START,
   the byte read ahead given back at the NACK and the ports preloaded again); the second pass's names
   end in "/nostretch". */
#include <stdio.h>
#include <string.h>

#include "bridge.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define INSNS_PER_TICK 40u

static uint64_t clock_us;
static uint64_t hal_now(void *ctx)
{
    (void)ctx;
    return clock_us;
}
static void hal_addr(void *ctx, uint8_t addr, int on)
{
    (void)ctx;
    (void)addr;
    (void)on;
}
static void hal_link(void *ctx, const uint8_t *p, size_t n)
{
    (void)ctx;
    (void)p;
    (void)n;
}
static size_t hal_sbus(void *ctx, const uint8_t *p, size_t n)
{
    (void)ctx;
    (void)p;
    return n;
}

struct cost {
    const char *name;
    uint32_t calls;
    uint64_t sum;
    uint32_t max, locked_max;
};

enum { START_W, WRITE, START_R, READ, NACK, STOP, LINK_RX, LINK_RX_CONFIG, POLL, IDLE, KINDS };
static const char *const NAMES[KINDS] = { "i2c_start_write",    "i2c_write",      "i2c_start_read",
                                          "i2c_read",           "i2c_nack",       "i2c_stop",
                                          "link_rx_imu_sample", "link_rx_config", "poll",
                                          "idle_frames_out" };
static struct cost passes[2][KINDS];
static struct cost *costs = passes[0];

static int hal_preload(void *ctx, unsigned port, uint8_t byte)
{
    (void)ctx;
    (void)port;
    (void)byte;
    return 1;
}

static uint32_t ticks_since(uint32_t from) { return ((from - SYST_CVR) & 0xFFFFFFu) * INSNS_PER_TICK; }

static uint32_t t0, locked_at, locked_longest;
static unsigned depth;

static uint32_t hal_lock(void *ctx)
{
    (void)ctx;
    if (depth == 0)
        locked_at = SYST_CVR;
    return depth++;
}

static void hal_unlock(void *ctx, uint32_t saved)
{
    (void)ctx;
    depth = saved;
    if (depth == 0) {
        uint32_t held = ticks_since(locked_at);
        if (held > locked_longest)
            locked_longest = held;
    }
}

static void begin(void)
{
    locked_longest = 0;
    t0 = SYST_CVR;
}

static void end(int kind)
{
    uint32_t insns = ticks_since(t0);
    struct cost *c = &costs[kind];
    c->calls++;
    c->sum += insns;
    if (insns > c->max)
        c->max = insns;
    if (locked_longest > c->locked_max)
        c->locked_max = locked_longest;
}

static void send(struct bridge *b, struct bridge_msg *m, int kind)
{
    uint8_t wire[LINK_WIRE_MAX];
    static uint8_t seq;
    m->seq = seq++;
    size_t n = link_frame(m, wire);
    if (kind >= 0)
        begin();
    bridge_link_rx(b, wire, n);
    if (kind >= 0)
        end(kind);
}

#define BIT_NS 2500u /* 400 kHz */

static void serve(int nostretch)
{
    static struct bridge b;
    struct bridge_hal hal = { .now_us = hal_now,
                              .i2c_addr_enable = hal_addr,
                              .link_tx = hal_link,
                              .sbus_tx = hal_sbus,
                              .i2c_preload = nostretch ? hal_preload : NULL,
                              .lock = hal_lock,
                              .unlock = hal_unlock };
    struct bridge_cfg cfg = bridge_defaults();
    costs = passes[nostretch];
    clock_us = 0;
    bridge_init(&b, &hal, &cfg);

    struct bridge_msg m;
    memset(&m, 0, sizeof m);
    m.id = BRIDGE_HELLO;
    m.u.hello.version = BRIDGE_PROTOCOL_VERSION;
    send(&b, &m, -1);
    memset(&m, 0, sizeof m); /* what the rig sends at the start of a run: the chips reset */
    m.id = BRIDGE_CONFIG;
    m.u.config.mpu_addr = 0x68;
    m.u.config.hmc_addr = 0x1E;
    m.u.config.baro_addr = 0x77;
    m.u.config.sbus_period_ms = 14;
    m.u.config.capture_channels = 4;
    send(&b, &m, LINK_RX_CONFIG);
    bridge_idle(&b);
    const uint8_t setup[][2] = { { 0x6B, 0x00 }, { 0x1A, 0x01 } }; /* wake; DLPF 1: 1 kHz samples */
    for (unsigned i = 0; i < 2; i++) {
        bridge_i2c_start(&b, 1000u * i, 0x68, 0);
        bridge_i2c_write(&b, 1000u * i + 25000u, setup[i][0]);
        bridge_i2c_write(&b, 1000u * i + 50000u, setup[i][1]);
        bridge_i2c_stop(&b, 1000u * i + 75000u);
    }
    for (unsigned k = 0; k < 2000; k++) {
        clock_us = 1000u * k;
        memset(&m, 0, sizeof m);
        m.id = BRIDGE_IMU_SAMPLE;
        m.u.imu_sample.valid_us = clock_us + 2000u;
        m.u.imu_sample.accel[0] = 0.1f * (float)(k % 7);
        m.u.imu_sample.accel[2] = -9.8f;
        m.u.imu_sample.gyro[1] = 0.01f * (float)(k % 5);
        m.u.imu_sample.temp_c = 25.0f;
        send(&b, &m, LINK_RX);
        begin();
        bridge_idle(&b); /* as the firmware's main loop, interrupts on: the sample encoded ahead */
        end(IDLE);
        begin();
        bridge_poll(&b);
        end(POLL);
        uint64_t t = clock_us * 1000u + 500000u;
        begin();
        bridge_i2c_start(&b, t, 0x68, 0);
        end(START_W);
        t += 9 * BIT_NS;
        begin();
        bridge_i2c_write(&b, t, 0x3B);
        end(WRITE);
        t += 10 * BIT_NS;
        begin();
        bridge_i2c_start(&b, t, 0x68, 1); /* (nostretch: the first byte read in here) */
        end(START_R);
        for (unsigned i = nostretch ? 1u : 0u; i < 14 + (unsigned)nostretch; i++) { /* (+ the one ahead) */
            t += 9 * BIT_NS;
            begin();
            (void)bridge_i2c_read(&b, t);
            end(READ);
        }
        if (nostretch) {
            begin();
            bridge_i2c_unread(&b);
            bridge_i2c_preload_all(&b);
            end(NACK);
        }
        begin();
        bridge_i2c_stop(&b, t);
        end(STOP);
    }
    for (unsigned i = 0; i < KINDS; i++)
        if (costs[i].calls)
            printf("%s%s calls %lu mean_insns %lu max_insns %lu locked_max %lu\n", NAMES[i],
                   nostretch ? "/nostretch" : "", (unsigned long)costs[i].calls,
                   (unsigned long)(costs[i].sum / costs[i].calls), (unsigned long)costs[i].max,
                   (unsigned long)costs[i].locked_max);
}

int main(void)
{
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0;
    SYST_CSR = 5; /* on, the processor clock, no interrupt */
    serve(0);
    serve(1);
    return 0;
}
