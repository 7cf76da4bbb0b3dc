/*
 * The STM32F4's I2C controller (I2C v1), RM0090 section 27, in master mode: the registers CR1, CR2, OAR1,
 * OAR2, DR, SR1, SR2, CCR and TRISE, the events and their clear sequences (SB: SR1 read then DR write;
 * ADDR: SR1 read then SR2 read; BTF, TXE and RXNE by DR), the receiver's ACK/NACK with POS (ACK decides
 * the byte in the shift register, or with POS the byte after it), the stretch while DR and the shift
 * register are both full (BTF), START and STOP after the byte under way, NACK of an address or a data
 * byte (AF), and the event and error interrupt lines.
 *
 * The bus moves in virtual time: a START, an address or data byte (nine SCL periods) and a STOP take the
 * time their SCL clock gives (CCR, with CR2.FREQ as the APB clock), so an interrupt-driven driver meets
 * its events one at a time, as on the chip. The slaves are QEMU I2C devices on the controller's bus.
 * A phase's end is carried out at its instant by a QEMU timer only when something must happen then (an
 * interrupt enabled); otherwise when the firmware next touches the controller, or the link reaches a
 * time, at the instant the phase ended (the slaves see that time, rig_i2c_event_ns). What the firmware
 * reads is the same either way; a QEMU timer under icount costs a wake-up of QEMU's main loop, and a
 * polling driver's transfers were twelve thousand of them a simulated second.
 * SCL and SDA as the GPIO pins show them (qdev GPIO inputs "scl-sda" 0 and 1) reach the controller and
 * the bus, and the bus drives the pins from outside ("scl-sda-drive": the pull-ups, or a slave holding
 * SDA low), so the pins' IDR shows the lines. A software reset or PE = 0 puts nothing on the wire: a slave that was sending a byte is left
 * holding SDA low, so SR2.BUSY (set while SCL or SDA is low, with PE) stays set and a START waits for a
 * free bus, as on the chip. A firmware's bus unstick frees it: nine SCL pulses by GPIO clock the byte
 * out (the slave gives it and sees it NACKed) and release SDA; SDA rising while SCL is high is a STOP
 * condition, which ends the transfer on the bus and clears BUSY.
 *
 * DMA requests (27.3.8): with CR2.DMAEN, RXNE of a receiver and TXE of a transmitter (its address
 * acknowledged) raise the "dma" lines (0: receive, 1: transmit), which the DMA's read of DR or write to it
 * takes down; the DMA's EOT_1 ("dma-eot1", when it has taken the last-but-one byte) with CR2.LAST makes
 * the master NACK the next byte received, the last, so the firmware sends the STOP when the DMA's
 * transfer completes. DR takes byte accesses (the DMA's, PSIZE 8 bits) as the chip's APB does.
 *
 * Not modelled: slave mode, SMBus, PEC, arbitration and bus errors (no other master, no misplaced START or
 * STOP), the TRISE rise-time limit.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"

#define APB1ENR 0x40

/* RM0090 table 133 (I2C register map and reset values) */
static const RigRegister i2c_registers[] = {
    { 0x00, "CR1", 0x0000, 0xBFFB },   /* PE ... SWRST (bits 2 and 14 reserved) */
    { 0x04, "CR2", 0x0000, 0x1F3F },   /* FREQ, ITERREN, ITEVTEN, ITBUFEN, DMAEN, LAST */
    { 0x08, "OAR1", 0x0000, 0xC3FF },  /* ADD, bit 14 (kept at 1 by software), ADDMODE */
    { 0x0C, "OAR2", 0x0000, 0x00FF },  /* ENDUAL, ADD2 */
    { 0x10, "DR", 0x0000, 0x00FF },    /* DR */
    { 0x14, "SR1", 0x0000, 0xDF00 },   /* the error flags, cleared by writing 0 (rc_w0) */
    { 0x18, "SR2", 0x0000, 0x0000 },   /* read only */
    { 0x1C, "CCR", 0x0000, 0xCFFF },   /* CCR, DUTY, F/S */
    { 0x20, "TRISE", 0x0002, 0x003F }, /* TRISE */
};
enum { R_CR1, R_CR2, R_OAR1, R_OAR2, R_DR, R_SR1, R_SR2, R_CCR, R_TRISE };

#define CR1_PE (1u << 0)
#define CR1_START (1u << 8)
#define CR1_STOP (1u << 9)
#define CR1_ACK (1u << 10)
#define CR1_POS (1u << 11)
#define CR1_SWRST (1u << 15)
#define CR2_FREQ 0x3Fu
#define CR2_ITERREN (1u << 8)
#define CR2_ITEVTEN (1u << 9)
#define CR2_ITBUFEN (1u << 10)
#define CR2_DMAEN (1u << 11)
#define CR2_LAST (1u << 12)
#define SR1_SB (1u << 0)
#define SR1_ADDR (1u << 1)
#define SR1_BTF (1u << 2)
#define SR1_ADD10 (1u << 3)
#define SR1_STOPF (1u << 4)
#define SR1_RXNE (1u << 6)
#define SR1_TXE (1u << 7)
#define SR1_AF (1u << 10)
#define SR1_ERRORS 0xDF00u /* BERR, ARLO, AF, OVR, PECERR, TIMEOUT, SMBALERT */
#define SR2_MSL (1u << 0)
#define SR2_BUSY (1u << 1)
#define SR2_TRA (1u << 2)
#define CCR_CCR 0xFFFu
#define CCR_DUTY (1u << 14)
#define CCR_FS (1u << 15)

#define SCL_CLOCKS_PER_BYTE 9 /* eight data bits and the acknowledge */

/* One period of SCL in ns (27.6.8): standard mode T_high = T_low = CCR * T_PCLK1; fast mode T_low =
 * 2 T_high (DUTY 0) or 16/9 T_high (DUTY 1), T_high = CCR * T_PCLK1 (DUTY 1: 9 CCR) */
static int64_t scl_period_ns(const RigStm32I2cState *s)
{
    uint32_t mhz = MAX(s->cr2 & CR2_FREQ, 2u);
    uint32_t ccr = MAX(s->ccr & CCR_CCR, 1u);
    uint32_t periods = !(s->ccr & CCR_FS) ? 2 : (s->ccr & CCR_DUTY) ? 25 : 3;
    return (int64_t)periods * ccr * 1000 / mhz;
}

static bool i2c_clocked(RigStm32I2cState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, APB1ENR, s->apb1_bit);
}

static void update_irqs(RigStm32I2cState *s)
{
    bool buffer = (s->cr2 & CR2_ITBUFEN) && (s->sr1 & (SR1_TXE | SR1_RXNE));
    bool event = (s->sr1 & (SR1_SB | SR1_ADDR | SR1_BTF | SR1_ADD10 | SR1_STOPF)) || buffer;
    qemu_set_irq(s->ev_irq, (s->cr2 & CR2_ITEVTEN) && event);
    qemu_set_irq(s->er_irq, (s->cr2 & CR2_ITERREN) && (s->sr1 & SR1_ERRORS));
    bool dma[2] = {
        (s->cr2 & CR2_DMAEN) && (s->sr1 & SR1_RXNE) && !(s->sr2 & SR2_TRA),
        (s->cr2 & CR2_DMAEN) && (s->sr1 & SR1_TXE) && (s->sr2 & SR2_TRA) && !(s->sr1 & SR1_ADDR),
    };
    for (unsigned k = 0; k < 2; k++) {
        if (dma[k] != s->dma_level[k]) {
            s->dma_level[k] = dma[k];
            qemu_set_irq(s->dma[k], dma[k]);
        }
    }
}

/* The DMA took DR (@k 0) or filled it (1): its request is down until the flag is raised again */
static void dma_served(RigStm32I2cState *s, unsigned k)
{
    if (s->dma_level[k]) {
        s->dma_level[k] = false;
        qemu_set_irq(s->dma[k], 0);
    }
}

/* The DMA's EOT_1 (27.3.8): with LAST, the byte after the one it just took is NACKed */
static void dma_eot1(void *opaque, int line, int level)
{
    RigStm32I2cState *s = opaque;
    if (level && (s->cr2 & CR2_LAST) && !(s->sr2 & SR2_TRA)) {
        s->nack_last = true;
    }
}

/* The phase under way ends by the QEMU timer when its end must be seen at once: an interrupt (or a DMA
 * request) may follow it */
static void arm(RigStm32I2cState *s)
{
    if (s->phase != RIG_I2C_IDLE && (s->cr2 & (CR2_ITEVTEN | CR2_ITERREN | CR2_DMAEN))) {
        timer_mod(s->timer, s->phase_end_ns);
    } else {
        timer_del(s->timer);
    }
}

/* The bus takes @ns for @phase, from now or from the end of the phase before */
static void schedule(RigStm32I2cState *s, RigI2cPhase phase, int64_t ns)
{
    s->phase = phase;
    s->phase_end_ns = (s->event_ns >= 0 ? s->event_ns : qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL)) + ns;
    if (s->event_ns < 0) {
        arm(s); /* (a phase's end arms the next after its interrupt: catch_up) */
    }
}

/* The slave sends the next byte */
static void receive_next(RigStm32I2cState *s) { schedule(s, RIG_I2C_RX_BYTE, SCL_CLOCKS_PER_BYTE * scl_period_ns(s)); }

/* With nothing on the wire (a byte done, SCL stretched or the slave silent) a START or STOP asked for
 * goes out; none while ADDR waits to be cleared (the master holds SCL low then) */
static void kick(RigStm32I2cState *s)
{
    if (s->phase != RIG_I2C_IDLE || !(s->cr1 & CR1_PE) || (s->sr1 & SR1_ADDR)) {
        return;
    }
    if ((s->cr1 & CR1_START) && (!(s->sr2 & SR2_BUSY) || (s->sr2 & SR2_MSL))) {
        schedule(s, RIG_I2C_START, scl_period_ns(s));
    } else if ((s->cr1 & CR1_STOP) && (s->sr2 & SR2_MSL)) {
        schedule(s, RIG_I2C_STOP, scl_period_ns(s));
    }
}

bool rig_i2c_repeated_start;
int64_t rig_i2c_event_ns = -1;

static void start_done(RigStm32I2cState *s)
{
    s->cr1 &= ~CR1_START;
    if (i2c_bus_busy(s->bus)) {
        /* a repeated START: QEMU's bus keeps the slave addressed before (it does not scan again), so
         * that transfer ends here and the address byte starts the next one; the slaves are told it is
         * no STOP (rig_i2c_repeated_start) */
        rig_i2c_repeated_start = true;
        i2c_end_transfer(s->bus);
        rig_i2c_repeated_start = false;
    }
    s->sr1 = (s->sr1 & ~(SR1_TXE | SR1_BTF)) | SR1_SB;
    s->sr2 = (s->sr2 & ~SR2_TRA) | SR2_MSL | SR2_BUSY;
    s->shift_full = false;
    s->receiving = false;
    s->slave_sends = false;
}

static void address_done(RigStm32I2cState *s)
{
    bool read = s->address & 1;
    if (i2c_start_transfer(s->bus, s->address >> 1, read) != 0) {
        s->sr1 |= SR1_AF; /* no acknowledge: the master waits for a STOP or a START */
        return;
    }
    s->sr1 |= SR1_ADDR;
    s->slave_sends = read;
    s->ack_next = s->cr1 & CR1_ACK; /* with POS: the first byte's acknowledge */
    if (!read) {
        s->sr2 |= SR2_TRA;
        s->sr1 |= SR1_TXE;
    }
}

static void transmit_done(RigStm32I2cState *s)
{
    if (i2c_send(s->bus, s->shift) != 0) {
        s->sr1 |= SR1_AF;
    } else if (!(s->sr1 & SR1_TXE)) { /* the next byte waits in DR */
        s->shift = s->dr;
        s->sr1 |= SR1_TXE;
        schedule(s, RIG_I2C_TX_BYTE, SCL_CLOCKS_PER_BYTE * scl_period_ns(s));
    } else {
        s->sr1 |= SR1_BTF; /* DR and the shift register empty: SCL stretched */
    }
}

static void receive_done(RigStm32I2cState *s)
{
    uint8_t byte = i2c_recv(s->bus);
    /* POS = 0: ACK decides the byte just received; POS = 1: it decided at the end of the byte before
     * (or of the address), so RM0090's two-byte sequence clears ACK before the first byte ends */
    bool ack = ((s->cr1 & CR1_POS) ? s->ack_next : (s->cr1 & CR1_ACK)) && !s->nack_last;
    s->ack_next = s->cr1 & CR1_ACK;
    s->nack_last = false;
    if (!ack) {
        i2c_nack(s->bus);
    }
    if (s->sr1 & SR1_RXNE) { /* DR still full: the byte stays in the shift register, SCL stretched */
        s->shift = byte;
        s->shift_full = true;
        s->sr1 |= SR1_BTF;
    } else {
        s->dr = byte;
        s->sr1 |= SR1_RXNE;
    }
    s->receiving = ack;
    s->slave_sends = ack;
    if (ack && !s->shift_full && !(s->cr1 & (CR1_START | CR1_STOP))) {
        receive_next(s);
    }
}

static void stop_done(RigStm32I2cState *s)
{
    s->cr1 &= ~CR1_STOP;
    i2c_end_transfer(s->bus);
    s->slave_sends = false;
    s->sr1 &= ~(SR1_TXE | SR1_BTF);
    s->sr2 &= ~(SR2_MSL | SR2_BUSY | SR2_TRA);
    s->receiving = false;
}

static void phase_done(RigStm32I2cState *s)
{
    RigI2cPhase phase = s->phase;
    s->phase = RIG_I2C_IDLE;
    switch (phase) {
    case RIG_I2C_START:
        start_done(s);
        break;
    case RIG_I2C_ADDRESS:
        address_done(s);
        break;
    case RIG_I2C_TX_BYTE:
        transmit_done(s);
        break;
    case RIG_I2C_RX_BYTE:
        receive_done(s);
        break;
    case RIG_I2C_STOP:
        stop_done(s);
        break;
    case RIG_I2C_IDLE:
        break;
    }
    kick(s);
    update_irqs(s);
}

/* Every phase that has ended by now carried out, each at its own instant, then the QEMU timer armed for
 * the next: after the phase's interrupt is raised, since under icount with the core asleep (WFI) arming a
 * timer moves virtual time to it at once, and the interrupt would come a phase late. Not again from
 * inside (a DMA the phase's request started reads DR) */
static void catch_up(void *opaque)
{
    RigStm32I2cState *s = opaque;
    if (s->event_ns >= 0) {
        return;
    }
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    while (s->phase != RIG_I2C_IDLE && s->phase_end_ns <= now) {
        s->event_ns = rig_i2c_event_ns = s->phase_end_ns;
        phase_done(s);
        s->event_ns = rig_i2c_event_ns = -1;
    }
    arm(s);
}

/* Everything back to reset (nothing goes on the wire: the slave of a transfer under way still waits) */
static void i2c_clear(RigStm32I2cState *s)
{
    timer_del(s->timer);
    s->cr1 = s->cr2 = s->oar1 = s->oar2 = s->ccr = s->sr1 = s->sr2 = s->sr1_seen = 0;
    s->trise = i2c_registers[R_TRISE].reset;
    s->dr = s->shift = s->address = 0;
    s->shift_full = s->receiving = s->ack_next = s->slave_sends = s->nack_last = false;
    s->phase = RIG_I2C_IDLE;
}

/* SDA as the controller sees it: the pin, or low while an abandoned slave holds it */
static bool sda_level(const RigStm32I2cState *s) { return s->sda && !s->sda_held; }

/* What the bus puts on the pins (their outside drivers): the pull-ups, or SDA held low by a slave */
static void drive_lines(RigStm32I2cState *s)
{
    qemu_set_irq(s->line_out[0], 1);
    qemu_set_irq(s->line_out[1], !s->sda_held);
}

/* The controller stops without a STOP: a slave in the middle of sending keeps SDA low */
static void abandon(RigStm32I2cState *s)
{
    if (i2c_bus_busy(s->bus) && s->slave_sends) {
        s->sda_held = true;
        s->unstick_clocks = 0;
        drive_lines(s);
    }
    s->slave_sends = false;
}

static void write_cr1(RigStm32I2cState *s, uint32_t value)
{
    bool was_enabled = s->cr1 & CR1_PE;
    if (value & CR1_SWRST) { /* held in reset while SWRST is set */
        abandon(s);
        i2c_clear(s);
        s->cr1 = CR1_SWRST;
        return;
    }
    s->cr1 = value & i2c_registers[R_CR1].writable;
    if (!(s->cr1 & CR1_PE)) { /* 27.6.1: START, STOP, ACK and POS clear with PE; the flags too */
        abandon(s);
        timer_del(s->timer);
        s->cr1 &= ~(CR1_START | CR1_STOP | CR1_ACK | CR1_POS);
        s->sr1 = s->sr2 = s->sr1_seen = 0;
        s->shift_full = s->receiving = false;
        s->phase = RIG_I2C_IDLE;
        return;
    }
    if (!was_enabled && (!s->scl || !sda_level(s))) {
        s->sr2 |= SR2_BUSY;
    }
    kick(s);
}

/* ADDR cleared: a receiver clocks the first byte in, a transmitter sends what DR holds */
static void addr_cleared(RigStm32I2cState *s)
{
    s->sr1 &= ~SR1_ADDR;
    if (!(s->sr2 & SR2_TRA)) {
        receive_next(s);
    }
    kick(s);
}

static void write_dr(RigStm32I2cState *s, uint8_t value)
{
    if ((s->sr1 & SR1_SB) && (s->sr1_seen & SR1_SB)) { /* EV5: the address byte */
        s->sr1 &= ~SR1_SB;
        s->sr1_seen = 0;
        s->address = value;
        schedule(s, RIG_I2C_ADDRESS, SCL_CLOCKS_PER_BYTE * scl_period_ns(s));
        return;
    }
    s->dr = value;
    s->sr1 &= ~SR1_BTF;
    dma_served(s, 1);
    if ((s->sr2 & SR2_TRA) && !(s->sr1 & (SR1_ADDR | SR1_AF)) && s->phase == RIG_I2C_IDLE &&
        !(s->cr1 & (CR1_START | CR1_STOP))) {
        s->shift = value; /* straight into the shift register: DR empty again */
        s->sr1 |= SR1_TXE;
        schedule(s, RIG_I2C_TX_BYTE, SCL_CLOCKS_PER_BYTE * scl_period_ns(s));
    } else {
        s->sr1 &= ~SR1_TXE;
    }
}

static uint8_t read_dr(RigStm32I2cState *s)
{
    uint8_t value = s->dr;
    if (!(s->sr1 & SR1_RXNE)) {
        return value;
    }
    dma_served(s, 0);
    if (s->shift_full) { /* the stretched byte moves up; the slave goes on if it was acknowledged */
        s->dr = s->shift;
        s->shift_full = false;
        s->sr1 &= ~SR1_BTF;
        if (s->receiving && s->phase == RIG_I2C_IDLE && !(s->cr1 & (CR1_START | CR1_STOP))) {
            receive_next(s);
        }
        kick(s);
    } else {
        s->sr1 &= ~SR1_RXNE;
    }
    return value;
}

static uint64_t i2c_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32I2cState *s = opaque;
    uint64_t value = 0;
    if (!i2c_clocked(s)) {
        return 0;
    }
    catch_up(s);
    switch (rig_register_index(i2c_registers, ARRAY_SIZE(i2c_registers), offset)) {
    case R_CR1:
        return s->cr1;
    case R_CR2:
        return s->cr2;
    case R_OAR1:
        return s->oar1;
    case R_OAR2:
        return s->oar2;
    case R_DR:
        value = read_dr(s);
        break;
    case R_SR1:
        s->sr1_seen = s->sr1;
        return s->sr1;
    case R_SR2:
        value = s->sr2;
        if ((s->sr1 & SR1_ADDR) && (s->sr1_seen & SR1_ADDR)) { /* EV6 */
            s->sr1_seen = 0;
            addr_cleared(s);
        }
        break;
    case R_CCR:
        return s->ccr;
    case R_TRISE:
        return s->trise;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-i2c: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    update_irqs(s);
    return value;
}

static void i2c_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32I2cState *s = opaque;
    uint32_t v = (uint32_t)value;
    if (!i2c_clocked(s)) {
        return;
    }
    catch_up(s);
    switch (rig_register_index(i2c_registers, ARRAY_SIZE(i2c_registers), offset)) {
    case R_CR1:
        write_cr1(s, v);
        break;
    case R_CR2:
        s->cr2 = v & i2c_registers[R_CR2].writable;
        arm(s);
        break;
    case R_OAR1:
        s->oar1 = v & i2c_registers[R_OAR1].writable;
        break;
    case R_OAR2:
        s->oar2 = v & i2c_registers[R_OAR2].writable;
        break;
    case R_DR:
        write_dr(s, v & 0xFF);
        break;
    case R_SR1:
        s->sr1 &= v | ~SR1_ERRORS;
        break;
    case R_CCR: /* 27.6.8/27.6.9: configured only while the peripheral is disabled */
    case R_TRISE:
        if (s->cr1 & CR1_PE) {
            qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-i2c: CCR/TRISE written with PE set: ignored\n");
        } else if (offset == i2c_registers[R_CCR].offset) {
            s->ccr = v & i2c_registers[R_CCR].writable;
        } else {
            s->trise = v & i2c_registers[R_TRISE].writable;
        }
        break;
    case R_SR2:
        break;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-i2c: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    update_irqs(s);
}

static const MemoryRegionOps i2c_ops = {
    .read = i2c_read,
    .write = i2c_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .valid.min_access_size = 1, /* (RM0090: half-words or words; the DMA reads DR a byte at a time) */
    .valid.max_access_size = 4,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

/* A line's level from its GPIO pin (0: SCL, 1: SDA). 27.6.7: BUSY is set on SDA or SCL low and cleared
 * on a STOP condition */
static void line_changed(void *opaque, int line, int level)
{
    RigStm32I2cState *s = opaque;
    catch_up(s);
    bool sda_before = sda_level(s);
    if (line == 0) {
        bool falling = s->scl && !level;
        s->scl = level;
        if (falling && s->sda_held && ++s->unstick_clocks == SCL_CLOCKS_PER_BYTE) {
            (void)i2c_recv(s->bus); /* the slave's byte clocked out, and not acknowledged */
            i2c_nack(s->bus);
            s->sda_held = false;
            drive_lines(s); /* (SCL is low: SDA rising is no STOP) */
        }
    } else {
        s->sda = level;
    }
    bool stop = line == 1 && !sda_before && sda_level(s) && s->scl && !(s->sr2 & SR2_MSL);
    if (stop && i2c_bus_busy(s->bus) && s->phase == RIG_I2C_IDLE) {
        i2c_end_transfer(s->bus);
    }
    if (s->cr1 & CR1_PE) {
        if (!s->scl || !sda_level(s)) {
            s->sr2 |= SR2_BUSY;
        } else if (stop) {
            s->sr2 &= ~SR2_BUSY;
            kick(s); /* a START that waited for the bus */
        }
    }
    update_irqs(s);
}

static void i2c_reset(DeviceState *dev)
{
    RigStm32I2cState *s = RIG_STM32_I2C(dev);
    abandon(s); /* (RCC_APB1RSTR.I2C1RST in the middle of a read: as SWRST) */
    i2c_clear(s);
    drive_lines(s);
    update_irqs(s);
}

static void i2c_init(Object *obj)
{
    RigStm32I2cState *s = RIG_STM32_I2C(obj);
    memory_region_init_io(&s->iomem, obj, &i2c_ops, s, TYPE_RIG_STM32_I2C, 0x400);
    s->iomem.disable_reentrancy_guard = true; /* the DMA a register write asked for reads DR (update_irqs) */
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->ev_irq);
    sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->er_irq);
    s->bus = i2c_init_bus(DEVICE(obj), "i2c");
    s->scl = s->sda = true;
    qdev_init_gpio_in_named(DEVICE(obj), line_changed, "scl-sda", 2);
    qdev_init_gpio_out_named(DEVICE(obj), s->line_out, "scl-sda-drive", 2);
    s->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, catch_up, s);
    s->event_ns = -1;
    rig_link_sync_add(catch_up, s);
    qdev_init_gpio_out_named(DEVICE(obj), s->dma, "dma", 2);
    qdev_init_gpio_in_named(DEVICE(obj), dma_eot1, "dma-eot1", 1);
}

static Property i2c_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32I2cState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_UINT8("apb1-bit", RigStm32I2cState, apb1_bit, 21),
    DEFINE_PROP_END_OF_LIST(),
};

static void i2c_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = i2c_reset;
    device_class_set_props(dc, i2c_properties);
}

static const TypeInfo i2c_info = {
    .name = TYPE_RIG_STM32_I2C,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32I2cState),
    .instance_init = i2c_init,
    .class_init = i2c_class_init,
};

static void i2c_register_types(void) { type_register_static(&i2c_info); }

type_init(i2c_register_types)
