/* The bridge core: see bridge.h. */
#include "bridge.h"

#include <math.h>
#include <string.h>

struct bridge_cfg bridge_defaults(void)
{
    struct bridge_cfg c;
    memset(&c, 0, sizeof c);
    memcpy(c.id, "bridge", 6);
    c.clock_hz = 170000000u;
    c.status_period_us = 200000u;
    c.pulses_period_us = 2000u;
    c.capture = pwm_capture_defaults();
    return c;
}

/* the chip core's underrun counters, in STATUS's order (IMU, mag, baro) */
static const uint8_t UNDERRUNS[3] = { CHIP_COUNT_MPU_UNDERRUNS, CHIP_COUNT_HMC_UNDERRUNS, CHIP_COUNT_BARO_UNDERRUNS };

static uint64_t now_us(struct bridge *b) { return b->hal.now_us(b->hal.ctx); }

static uint32_t lock(struct bridge *b) { return b->hal.lock ? b->hal.lock(b->hal.ctx) : 0u; }

static void unlock(struct bridge *b, uint32_t saved)
{
    if (b->hal.unlock)
        b->hal.unlock(b->hal.ctx, saved);
}

void bridge_send(struct bridge *b, struct bridge_msg *msg)
{
    uint32_t k = lock(b);
    msg->seq = b->tx_seq++;
    if (b->out_head - b->out_tail < BRIDGE_OUTBOX) { /* (full: dropped, its sequence number spent) */
        b->outbox[b->out_head % BRIDGE_OUTBOX] = *msg;
        b->out_head++;
    }
    unlock(b, k);
}

/* Framing (the CRC, COBS) costs more than an I2C byte's time at 1 MHz: done here, with the lock held
   only to take the oldest message out of the outbox. */
void bridge_flush(struct bridge *b)
{
    for (;;) {
        struct bridge_msg m;
        uint32_t k = lock(b);
        int have = b->out_tail != b->out_head;
        if (have) {
            m = b->outbox[b->out_tail % BRIDGE_OUTBOX];
            b->out_tail++;
        }
        unlock(b, k);
        if (!have)
            return;
        if (m.id == BRIDGE_TIME_SYNC_REPLY)
            m.u.time_sync_reply.tx_us = now_us(b); /* the moment it leaves, not the moment it was queued */
        uint8_t wire[LINK_WIRE_MAX];
        size_t n = link_frame(&m, wire);
        if (n)
            b->hal.link_tx(b->hal.ctx, wire, n);
    }
}

static uint8_t chip_addr(const struct bridge *b, int chip)
{
    return chip == CHIP_MPU ? b->mpu_addr : chip == CHIP_HMC ? b->hmc_addr : b->baro_addr;
}

/* The port's target answers a chip's address only while the chip would: 0x1E while the MPU's bypass is
   on (GY-86), none while a bus fault keeps the chip silent. A target peripheral acknowledges its
   address before the core is asked, so a fault that only the core knew of would be ACKed; at the
   poll's pace (about 100 us) the hardware NACKs it as the real chip does (the core still refuses
   the bytes of a START that comes closer to a window's edge than that). */
static const uint8_t ADDRESS_ORDER[3] = { CHIP_MPU, CHIP_BARO, CHIP_HMC }; /* the HMC's last: it follows the MPU */

static int set_addresses(struct bridge *b, uint64_t t_ns)
{
    int changed = 0;
    for (int i = 0; i < 3; i++) {
        int chip = ADDRESS_ORDER[i];
        int on = chip_answers(&b->board, (uint8_t)chip, t_ns) &&
                 (chip != CHIP_HMC || b->topology == CHIP_TOPOLOGY_DIRECT || chip_mpu_bypass(&b->board));
        if (on != b->enabled[chip]) {
            b->enabled[chip] = (uint8_t)on;
            b->hal.i2c_addr_enable(b->hal.ctx, chip_addr(b, chip), on);
            changed = 1;
        }
    }
    return changed;
}

/* CONFIG's values (or the defaults at start): the chips reset to power-on. Rebuilding the chip board
   (some kilobytes cleared: 40 us on the M4) is done with the lock released: meanwhile the addresses
   are off and `offline` keeps the I2C events away from the board, as chips powering up answer
   nothing. */
static void configure(struct bridge *b, uint8_t topology, uint8_t mpu, uint8_t hmc, uint8_t baro, uint8_t sbus_ms,
                      uint8_t channels, uint8_t trace)
{
    uint32_t k = lock(b);
    for (int i = 0; i < 3; i++)
        if (b->enabled[ADDRESS_ORDER[i]])
            b->hal.i2c_addr_enable(b->hal.ctx, chip_addr(b, ADDRESS_ORDER[i]), 0);
    memset(b->enabled, 0, sizeof b->enabled);
    b->offline = 1;
    b->cur_chip = -1; /* a transaction under way: the rest of it is refused */
    unlock(b, k);
    b->topology = topology;
    b->mpu_addr = mpu;
    b->hmc_addr = hmc;
    b->baro_addr = baro;
    b->capture_channels = channels;
    b->trace = trace;
    chip_board_init(&b->board, topology ? CHIP_TOPOLOGY_DIRECT : CHIP_TOPOLOGY_GY86);
    memset(b->n.underrun_base, 0, sizeof b->n.underrun_base);
    sbus_out_init(&b->sbus, sbus_ms * 1000u);
    k = lock(b);
    b->offline = 0;
    b->guess0 = mpu;
    set_addresses(b, now_us(b) * 1000u);
    bridge_i2c_preload_all(b);
    unlock(b, k);
}

void bridge_init(struct bridge *b, const struct bridge_hal *hal, const struct bridge_cfg *cfg)
{
    memset(b, 0, sizeof *b);
    b->hal = *hal;
    b->cfg = *cfg;
    link_rx_init(&b->rx, 0);
    pwm_capture_init(&b->cap, &cfg->capture);
    configure(b, CHIP_TOPOLOGY_GY86, CHIP_ADDR_MPU, CHIP_ADDR_HMC, CHIP_ADDR_BARO, 14, PWM_CAPTURE_CHANNELS, 0);
    uint64_t t = now_us(b);
    b->last_rx_us = t;
    b->next_status_us = t;
    b->next_pulses_us = t;
}

/* ---------------------------------------------------------------- the board's bus */

/* the chip core's address for the board's, and the chip (-1: none of ours) */
static int core_addr(const struct bridge *b, uint8_t addr, uint8_t *out)
{
    if (addr == b->mpu_addr) {
        *out = CHIP_ADDR_MPU;
        return CHIP_MPU;
    }
    if (addr == b->hmc_addr) {
        *out = CHIP_ADDR_HMC;
        return CHIP_HMC;
    }
    if (addr == b->baro_addr) {
        *out = CHIP_ADDR_BARO;
        return CHIP_BARO;
    }
    *out = 0; /* the general call: the chips never acknowledge it */
    return -1;
}

/* ---------------------------------------------------------------- preloading (hal.h i2c_preload) */

static unsigned port_of(const struct bridge *b, uint8_t addr) { return addr == b->hmc_addr ? 1u : 0u; }

/* The first byte of the read the port expects next, at the chips' present time (a chip that would not
   answer gets 0xFF: the lines stay high), given to the port to hold. */
static void preload(struct bridge *b, unsigned port)
{
    if (!b->hal.i2c_preload)
        return;
    uint8_t addr = port ? b->hmc_addr : b->guess0, a, byte = 0xFF;
    uint64_t t = b->board.now_ns;
    if (b->offline || core_addr(b, addr, &a) < 0 || !chip_read_preview(&b->board, t, a, &byte))
        byte = 0xFF;
    if (b->hal.i2c_preload(b->hal.ctx, port, byte)) {
        struct bridge_preload *pr = &b->pre[port];
        pr->addr = addr;
        pr->byte = byte;
        pr->loaded = 1;
        pr->t_ns = t;
    }
}

/* what moves a chip's registers as time passes: sample instants, measurements, conversions (a bus
   fault's window too: with faults set, every time) */
static uint32_t generation(const struct bridge *b)
{
    return chip_count(&b->board, CHIP_COUNT_MPU_SAMPLES) + chip_count(&b->board, CHIP_COUNT_HMC_MEASUREMENTS) +
           chip_count(&b->board, CHIP_COUNT_BARO_CONVERSIONS);
}

void bridge_i2c_preload_all(struct bridge *b)
{
    if (!b->hal.i2c_preload)
        return;
    for (unsigned p = 0; p < BRIDGE_I2C_PORTS; p++)
        preload(b, p);
    b->preload_gen = generation(b);
}

/* after the chips' time moved: a preview costs more than a byte's time at 1 MHz with interrupts masked,
   so the ports are preloaded again only when something they could hold changed */
static void preload_if_moved(struct bridge *b)
{
    if (!b->hal.i2c_preload)
        return;
    uint32_t gen = generation(b);
    int faults = 0;
    for (int c = CHIP_MPU; c <= CHIP_BARO; c++)
        faults |= b->board.faults[c].n > 0;
    if (gen != b->preload_gen || faults)
        bridge_i2c_preload_all(b);
}

static void trace_flush(struct bridge *b)
{
    if (!b->trace || b->cur_chip < 0)
        return;
    struct bridge_msg m;
    memset(&m, 0, sizeof m);
    m.id = BRIDGE_TRACE;
    m.u.trace.t_us = b->trace_t_ns / 1000u;
    m.u.trace.addr = b->cur_addr;
    m.u.trace.read = b->cur_read;
    m.u.trace.len = b->cur_bytes > 255 ? 255 : (uint8_t)b->cur_bytes;
    memcpy(m.u.trace.data, b->trace_data, b->trace_len);
    bridge_send(b, &m);
}

static void trace_byte(struct bridge *b, uint8_t v)
{
    if (b->trace_len < sizeof b->trace_data)
        b->trace_data[b->trace_len++] = v;
    b->cur_bytes++;
}

/* With i2c_preload a read's first byte is on the wire already: the one preloaded for its port. A read
   from the address it was taken for starts at the chips' time it was taken at (so it is the byte the
   chip gives, even if a sample instant passed since); another address, or a byte that is not the
   chip's, is a miss: counted, and the chip's own first byte is read and dropped, as the board took one. */
int bridge_i2c_start(struct bridge *b, uint64_t t_ns, uint8_t addr, int read)
{
    trace_flush(b); /* a repeated START ends the message before it */
    if (b->offline) {
        b->cur_chip = -1;
        return 0;
    }
    uint8_t a;
    int chip = core_addr(b, addr, &a);
    unsigned port = port_of(b, addr);
    struct bridge_preload *pr = &b->pre[port];
    int preloaded = read && b->hal.i2c_preload != NULL;
    int matched = preloaded && pr->loaded && pr->addr == addr;
    uint64_t before = b->board.now_ns;
    if (b->cur_chip < 0)
        b->txn_t_ns = t_ns;
    int ack = chip_start(&b->board, matched ? pr->t_ns : t_ns, a, read != 0);
    if (!ack && chip >= 0)
        b->n.i2c_errors++; /* one of our chips did not answer: a bus fault, or 0x1E out of bypass */
    if (ack)
        b->n.i2c_acked++;
    b->cur_chip = ack ? chip : -1;
    b->cur_addr = addr;
    b->cur_read = (uint8_t)(read != 0);
    b->cur_bytes = 0;
    b->trace_len = 0;
    b->trace_t_ns = t_ns;
    if (ack && port == 0)
        b->guess0 = addr;
    if (preloaded) {
        uint8_t sent = pr->loaded ? pr->byte : 0xFF;
        pr->loaded = 0; /* it went out */
        if (ack && (bridge_i2c_read(b, t_ns) != sent || !matched))
            b->n.preload_misses++;
    }
    if (b->board.now_ns != before)
        preload_if_moved(b); /* what the other port holds may be stale */
    return ack;
}

/* REG_WRITE up for a byte written (not the pointer; the MS5611's command only) */
static void reg_write(struct bridge *b, uint64_t t_ns, uint8_t byte)
{
    unsigned i = b->cur_bytes;
    trace_byte(b, byte);
    struct bridge_msg m;
    memset(&m, 0, sizeof m);
    m.id = BRIDGE_REG_WRITE;
    m.u.reg_write.t_us = t_ns / 1000u;
    m.u.reg_write.addr = b->cur_addr;
    if (b->cur_chip == CHIP_BARO) {
        if (i > 0)
            return; /* the MS5611 ignores what follows its command */
        m.u.reg_write.reg = byte;
    } else if (i == 0) {
        b->ptr = byte; /* the register pointer */
        return;
    } else {
        m.u.reg_write.reg = (uint8_t)(b->ptr + i - 1);
        m.u.reg_write.value = byte;
    }
    bridge_send(b, &m);
}

int bridge_i2c_write(struct bridge *b, uint64_t t_ns, uint8_t byte)
{
    if (b->cur_chip < 0)
        return 0; /* nobody was addressed: nobody acknowledges */
    chip_write_byte(&b->board, byte);
    reg_write(b, t_ns, byte);
    preload(b, port_of(b, b->cur_addr)); /* a repeated START may read from the pointer just written */
    return 1;
}

uint8_t bridge_i2c_read(struct bridge *b, uint64_t t_ns)
{
    (void)t_ns; /* (the chip core moves time only at a START) */
    if (b->offline)
        return 0xFF;
    uint8_t v = chip_read_byte(&b->board);
    if (b->cur_chip >= 0)
        trace_byte(b, v);
    return v;
}

void bridge_idle(struct bridge *b)
{
    chip_prepare(&b->board);
    bridge_flush(b);
}

void bridge_i2c_unread(struct bridge *b)
{
    if (b->cur_chip < 0 || !b->cur_read || !b->cur_bytes)
        return;
    chip_unread_byte(&b->board);
    if (b->trace_len == b->cur_bytes)
        b->trace_len--;
    b->cur_bytes--;
}

void bridge_i2c_stop(struct bridge *b, uint64_t t_ns)
{
    trace_flush(b);
    b->cur_chip = -1;
    if (b->offline)
        return;
    chip_stop(&b->board);
    set_addresses(b, t_ns); /* the bypass may have changed */
    bridge_i2c_preload_all(b);
}

/* ---------------------------------------------------------------- capture */

void bridge_capture_edge(struct bridge *b, unsigned channel, int level, uint32_t count, uint64_t t_us)
{
    if (channel >= b->capture_channels) {
        b->cap.glitches++;
        return;
    }
    pwm_capture_edge(&b->cap, channel, level, count, t_us);
}

/* ---------------------------------------------------------------- the host's messages */

static int finite3(const float *v) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

static void hello(struct bridge *b, const struct bridge_hello *h)
{
    struct bridge_msg m;
    memset(&m, 0, sizeof m);
    m.id = BRIDGE_HELLO_REPLY;
    m.u.hello_reply.version = BRIDGE_PROTOCOL_VERSION;
    m.u.hello_reply.nonce = h->nonce;
    m.u.hello_reply.core_version = BRIDGE_CORE_VERSION;
    memcpy(m.u.hello_reply.bridge_id, b->cfg.id, sizeof m.u.hello_reply.bridge_id);
    memcpy(m.u.hello_reply.firmware_sha256, b->cfg.fw_sha, sizeof m.u.hello_reply.firmware_sha256);
    m.u.hello_reply.clock_hz = b->cfg.clock_hz;
    b->agreed = h->version == BRIDGE_PROTOCOL_VERSION;
    if (b->agreed) { /* the link's counters start again (this frame counts as the first) */
        uint8_t seq = b->rx.last_seq;
        int up = b->rx.up;
        link_rx_init(&b->rx, up);
        b->rx.ok = 1;
        b->rx.have_seq = 1;
        b->rx.last_seq = seq;
        b->n.late_samples = b->n.refused = b->n.sbus_dropped = 0;
        b->cap.glitches = 0;
        uint32_t k = lock(b); /* the I2C events count these */
        b->n.i2c_errors = b->n.i2c_acked = b->n.preload_misses = 0;
        for (int c = 0; c < 3; c++)
            b->n.underrun_base[c] = chip_count(&b->board, UNDERRUNS[c]);
        unlock(b, k);
    }
    bridge_send(b, &m);
}

static int config(struct bridge *b, const struct bridge_config *c)
{
    if (c->topology > 1 || (c->mpu_addr != 0x68 && c->mpu_addr != 0x69) || c->hmc_addr != 0x1E ||
        (c->baro_addr != 0x76 && c->baro_addr != 0x77) || c->capture_channels > PWM_CAPTURE_CHANNELS || c->trace > 1 ||
        c->sbus_period_ms > 100)
        return -1;
    struct pwm_capture_cfg cap = b->cap.cfg, limits = pwm_capture_defaults(); /* the port's timer stays */
    if (c->pulse_min_us || c->pulse_max_us || c->period_min_us) { /* the ESC protocol's (OneShot125: 125..250 us) */
        if (!c->pulse_min_us || c->pulse_min_us >= c->pulse_max_us || !c->period_min_us)
            return -1;
        limits.min_width_us = c->pulse_min_us;
        limits.max_width_us = c->pulse_max_us;
        limits.min_period_us = c->period_min_us;
    }
    cap.min_width_us = limits.min_width_us;
    cap.max_width_us = limits.max_width_us;
    cap.min_period_us = limits.min_period_us;
    pwm_capture_init(&b->cap, &cap);
    configure(b, c->topology, c->mpu_addr, c->hmc_addr, c->baro_addr, c->sbus_period_ms, c->capture_channels, c->trace);
    return 0;
}

static void late(struct bridge *b, uint64_t valid_us, uint64_t t_us)
{
    if (valid_us < t_us)
        b->n.late_samples++;
}

static int fault(struct bridge *b, const struct bridge_fault *f)
{
    int chip = f->target == BRIDGE_FAULT_TARGET_MPU        ? CHIP_MPU
               : f->target == BRIDGE_FAULT_TARGET_HMC      ? CHIP_HMC
               : f->target == BRIDGE_FAULT_TARGET_BARO_BUS ? CHIP_BARO
                                                           : -1;
    int kind = f->kind == BRIDGE_FAULT_KIND_OFF            ? CHIP_FAULT_OFF
               : f->kind == BRIDGE_FAULT_KIND_INTERMITTENT ? CHIP_FAULT_INTERMITTENT
               : f->kind == BRIDGE_FAULT_KIND_GARBAGE      ? CHIP_FAULT_GARBAGE
                                                           : -1;
    if (chip < 0 || kind < 0 || f->end_us <= f->start_us || f->end_us > UINT64_MAX / 1000u)
        return -1;
    uint64_t period_ns = 0, duty_ns = 0;
    if (kind == CHIP_FAULT_INTERMITTENT) {
        if (!(f->period_s > 0.0f && f->period_s < 1000.0f && f->duty >= 0.0f && f->duty <= 1.0f))
            return -1;
        period_ns = (uint64_t)((double)f->period_s * 1e9);
        duty_ns = (uint64_t)((double)f->duty * (double)period_ns);
        if (!period_ns)
            return -1;
    }
    uint32_t k = lock(b);
    int ok = chip_bus_fault_add(&b->board, (uint8_t)chip, (uint8_t)kind, f->start_us * 1000u, f->end_us * 1000u,
                                period_ns, duty_ns);
    unlock(b, k);
    return ok ? 0 : -1;
}

/* One good frame from the host, received at t_us: 0 acted on, -1 refused (nothing applied). The
   lock is taken around what the I2C events share (the chips, their counters), nothing longer. */
static int dispatch(struct bridge *b, const struct bridge_msg *msg, uint64_t t_us)
{
    if (msg->id == BRIDGE_HELLO) {
        hello(b, &msg->u.hello);
        return 0;
    }
    if (!b->agreed)
        return -1;
    switch (msg->id) {
    case BRIDGE_CONFIG:
        return config(b, &msg->u.config);
    case BRIDGE_IMU_SAMPLE: {
        const struct bridge_imu_sample *s = &msg->u.imu_sample;
        if (!finite3(s->accel) || !finite3(s->gyro) || !isfinite(s->temp_c) || s->valid_us > UINT64_MAX / 1000u)
            return -1;
        late(b, s->valid_us, t_us);
        double v[7] = { s->accel[0], s->accel[1], s->accel[2], s->gyro[0], s->gyro[1], s->gyro[2], s->temp_c };
        uint32_t k = lock(b);
        chip_push_imu(&b->board, s->valid_us * 1000u, v); /* (full: the oldest made room) */
        unlock(b, k);
        return 0;
    }
    case BRIDGE_MAG_SAMPLE: {
        const struct bridge_mag_sample *s = &msg->u.mag_sample;
        if (!finite3(s->field) || s->valid_us > UINT64_MAX / 1000u)
            return -1;
        late(b, s->valid_us, t_us);
        double field[3] = { s->field[0], s->field[1], s->field[2] };
        uint32_t k = lock(b);
        chip_push_mag(&b->board, s->valid_us * 1000u, field);
        unlock(b, k);
        return 0;
    }
    case BRIDGE_BARO_SAMPLE: {
        const struct bridge_baro_sample *s = &msg->u.baro_sample;
        if (s->d1 > 0xFFFFFFu || s->d2 > 0xFFFFFFu || s->valid_us > UINT64_MAX / 1000u) /* 24-bit ADC words */
            return -1;
        late(b, s->valid_us, t_us);
        uint32_t k = lock(b);
        chip_push_baro(&b->board, s->valid_us * 1000u, s->d1, s->d2);
        unlock(b, k);
        return 0;
    }
    case BRIDGE_SBUS: {
        const struct bridge_sbus *s = &msg->u.sbus;
        for (int i = 0; i < SBUS_CHANNELS; i++)
            if (s->channels[i] > 0x7FF)
                return -1;
        if (s->flags & ~(0x0F | SBUS_OUT_OFF))
            return -1;
        sbus_out_set(&b->sbus, s->channels, s->flags, t_us);
        return 0;
    }
    case BRIDGE_TIME_SYNC: {
        struct bridge_msg m;
        memset(&m, 0, sizeof m);
        m.id = BRIDGE_TIME_SYNC_REPLY;
        m.u.time_sync_reply.id = msg->u.time_sync.id;
        m.u.time_sync_reply.rx_us = t_us;
        m.u.time_sync_reply.tx_us = now_us(b);
        bridge_send(b, &m);
        return 0;
    }
    case BRIDGE_FAULT:
        return fault(b, &msg->u.fault);
    case BRIDGE_HEARTBEAT:
        return 0;
    default:
        return -1; /* (the link decodes only down messages) */
    }
}

/* (the link's state is the main loop's alone: frames are taken apart with the lock released) */
void bridge_link_rx(struct bridge *b, const uint8_t *bytes, size_t n)
{
    uint64_t t = now_us(b);
    struct bridge_msg msg;
    for (size_t i = 0; i < n; i++) {
        if (!link_rx_byte(&b->rx, bytes[i], &msg))
            continue;
        b->last_rx_us = t;
        if (b->host_silent) {
            b->host_silent = 0;
            b->next_status_us = t; /* say it at once */
        }
        if (dispatch(b, &msg, t) < 0)
            b->n.refused++;
    }
}

/* ---------------------------------------------------------------- periodic work */

void bridge_status(struct bridge *b, struct bridge_status *s)
{
    memset(s, 0, sizeof *s);
    s->t_us = now_us(b);
    uint32_t k = lock(b);
    for (int c = 0; c < 3; c++)
        s->underruns[c] = chip_count(&b->board, UNDERRUNS[c]) - b->n.underrun_base[c];
    s->late_samples = b->n.late_samples;
    s->i2c_errors = b->n.i2c_errors;
    s->i2c_acked = b->n.i2c_acked;
    s->frames_ok = b->rx.ok;
    s->frames_bad = b->rx.bad;
    s->seq_gaps = b->rx.seq_gaps;
    s->refused = b->n.refused;
    s->pulse_glitches = b->cap.glitches;
    s->sbus_dropped = b->n.sbus_dropped;
    s->host_silent = (uint8_t)b->host_silent;
    s->i2c_preload_misses = b->n.preload_misses;
    unlock(b, k);
}

/* The widths as the DBC's capture frames, when the port has CAN (a capture device's job: the host may
   read the motors from a CAN bus instead of the link). A frame the port cannot queue is counted. */
static void can_capture(struct bridge *b, const uint16_t tenth_us[PWM_CAPTURE_CHANNELS])
{
    if (!b->hal.can_tx)
        return;
    for (unsigned k = 0; k < BRIDGE_CAN_CAPTURE_FRAMES; k++) {
        const struct bridge_can_capture *f = &BRIDGE_CAN_CAPTURE[k];
        uint8_t data[8] = { 0 }, covered[2 + 8];
        bridge_put_bits(data, f->pwm_start[0], 16, tenth_us[2 * k]);
        bridge_put_bits(data, f->pwm_start[1], 16, tenth_us[2 * k + 1]);
        bridge_put_bits(data, f->seq_start, f->seq_len, b->can_seq);
        covered[0] = (uint8_t)(f->id >> 8);
        covered[1] = (uint8_t)f->id;
        memcpy(covered + 2, data, f->crc_start / 8u);
        bridge_put_bits(data, f->crc_start, 16, link_crc16(covered, 2u + f->crc_start / 8u));
        if (b->hal.can_tx(b->hal.ctx, f->id, data, 8) != 0)
            b->n.can_dropped++;
    }
    b->can_seq++;
}

void bridge_poll(struct bridge *b)
{
    uint64_t t = now_us(b);
    uint32_t k = lock(b); /* the sample instants and the addresses: the I2C events' too */
    /* a transaction under way holds the chips' time, as the MPU-6050 holds its data registers while its
       serial interface is busy: a read after a repeated START gives the instant its first byte was
       preloaded at */
    uint64_t before = b->board.now_ns;
    if (b->cur_chip < 0 || t * 1000u > b->txn_t_ns + BRIDGE_HOLD_NS)
        chip_advance(&b->board, t * 1000u);
    if (set_addresses(b, t * 1000u))
        bridge_i2c_preload_all(b);
    else if (b->board.now_ns != before)
        preload_if_moved(b);
    unlock(b, k);
    uint64_t silent_for = t > b->last_rx_us ? t - b->last_rx_us : 0;
    int silent = silent_for > BRIDGE_HOST_SILENT_US;
    if (silent && !b->host_silent) {
        b->host_silent = 1;
        b->next_status_us = t; /* say it at once */
    }
    uint8_t frame[SBUS_FRAME];
    if (sbus_out_poll(&b->sbus, t, silent ? silent_for : 0, frame)) {
        size_t took = b->hal.sbus_tx(b->hal.ctx, frame, SBUS_FRAME);
        if (took < SBUS_FRAME)
            b->n.sbus_dropped += (uint32_t)(SBUS_FRAME - took);
    }
    struct bridge_msg m;
    int fresh = b->cap.pulses != b->pulses_sent;
    if (b->capture_channels && t >= b->next_pulses_us && (fresh || t - b->next_pulses_us >= BRIDGE_PULSES_EVERY_US)) {
        memset(&m, 0, sizeof m);
        m.id = BRIDGE_PULSES;
        m.u.pulses.t_us = b->cap.last_edge_us;
        pwm_capture_widths(&b->cap, t, m.u.pulses.width_tenth_us);
        for (unsigned i = b->capture_channels; i < PWM_CAPTURE_CHANNELS; i++)
            m.u.pulses.width_tenth_us[i] = 0;
        bridge_send(b, &m);
        can_capture(b, m.u.pulses.width_tenth_us);
        b->pulses_sent = b->cap.pulses;
        b->next_pulses_us = t + b->cfg.pulses_period_us;
    }
    if (t >= b->next_status_us) {
        memset(&m, 0, sizeof m);
        m.id = BRIDGE_STATUS;
        bridge_status(b, &m.u.status);
        bridge_send(b, &m);
        b->next_status_us = t + b->cfg.status_period_us;
    }
}
