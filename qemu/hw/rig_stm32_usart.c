/*
 * The STM32F4's USART (RM0090 section 30) in asynchronous mode: SR, DR, BRR, CR1, CR2, CR3 and GTPR, the
 * baud rate from BRR and the APB clock (USART1/USART6 on APB2, the others on APB1) with OVER8, and the
 * line in virtual time.
 *
 * Transmitter: a byte written to DR waits there (TXE = 0) until the shift register is free, then goes
 * out in its frame's time (start bit, M data bits, the stop bits of CR2.STOP; the parity bit is the last
 * data bit when PCE is set); TXE comes as the byte moves into the shift register, TC at the end of a
 * frame with none waiting. Setting TE sends an idle frame first (30.3.2). Each byte goes to the USART's
 * chardev when its frame ends; nothing else reaches QEMU's main loop (with -global
 * rig-stm32f4-usart.trace-bytes=on each is also a line on stderr with the instant its frame ended).
 *
 * Receiver: the sender's frames (rig_stm32_usart_receive: each frame's start, bits and baud, given ahead)
 * make the line's level in time, and the receiver reads it as the chip does (30.3.3): a falling edge starts a
 * frame, each bit is sampled at its middle (three samples, the majority taken; NF when they differ,
 * unless ONEBIT), the parity checked (PE) and the stop bit sampled (FE when low). So a sender whose baud,
 * word length or parity differ from the set-up gives the errors the chip gives: its bits fall where the
 * receiver samples them. RXNE (ORE when RXNE was still set: the byte is lost) comes at the stop bit's
 * middle, IDLE after a whole frame of idle line following a received frame.
 *
 * Time is lazy, as in rig_stm32_i2c.c: what happened by now is carried out when the firmware touches a
 * register, when the link reaches a time (rig_link_sync_add) or when the sender's next frame comes; a
 * QEMU timer runs only when an interrupt or a DMA request may need an event's instant; and with a DMA
 * stream feeding the transmitter or draining the receiver, only at the instant an interrupt is due
 * (tx_deadline here, rig_usart_rx_deadline in rig_stm32_usart_rx.c, the receiver's half).
 *
 * Not modelled: the synchronous mode (CLKEN), smartcard, IrDA, LIN and half-duplex modes, hardware flow
 * control (CTS stays 0), mute mode and wake-up (RWU, WAKE, ADD), break characters (SBK is cleared at
 * once, nothing goes on the wire), the start bit's extra samples (a start bit is its middle's majority).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties-system.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32_usart.h"

#define APB1ENR 0x40
#define APB2ENR 0x44

/* RM0090 table 146 (USART register map and reset values); UART4/UART5 lack the synchronous, smartcard
 * and flow-control bits (30.6: "not available for UART4 & UART5") */
static const RigRegister usart_registers[] = {
    { 0x00, "SR", 0x00C0, 0x0360 },   /* CTS, LBD, TC, RXNE cleared by writing 0 (rc_w0) */
    { 0x04, "DR", 0x0000, 0x01FF },   /* DR[8:0] */
    { 0x08, "BRR", 0x0000, 0xFFFF },  /* DIV_Mantissa[11:0], DIV_Fraction[3:0] */
    { 0x0C, "CR1", 0x0000, 0xBFFF },  /* OVER8, UE ... RWU, SBK (bit 14 reserved) */
    { 0x10, "CR2", 0x0000, 0x7F6F },  /* LINEN, STOP, CLKEN, CPOL, CPHA, LBCL, LBDIE, LBDL, ADD */
    { 0x14, "CR3", 0x0000, 0x0FFF },  /* ONEBIT, CTSIE, CTSE, RTSE, DMAT, DMAR, SCEN, NACK, HDSEL, IRLP, IREN, EIE */
    { 0x18, "GTPR", 0x0000, 0xFFFF }, /* GT, PSC */
};
static const RigRegister uart_registers[] = {
    { 0x00, "SR", 0x00C0, 0x0160 },   /* LBD, TC, RXNE */
    { 0x04, "DR", 0x0000, 0x01FF },   /* DR[8:0] */
    { 0x08, "BRR", 0x0000, 0xFFFF },  /* DIV_Mantissa[11:0], DIV_Fraction[3:0] */
    { 0x0C, "CR1", 0x0000, 0xBFFF },  /* as the USARTs' */
    { 0x10, "CR2", 0x0000, 0x706F },  /* LINEN, STOP, LBDIE, LBDL, ADD */
    { 0x14, "CR3", 0x0000, 0x08CF },  /* ONEBIT, DMAT, DMAR, HDSEL, IRLP, IREN, EIE */
    { 0x18, "GTPR", 0x0000, 0x0000 }, /* reserved */
};

static bool usart_clocked(RigStm32UsartState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, s->apb == 1 ? APB1ENR : APB2ENR, s->rcc_bit);
}

void rig_usart_update_irqs(RigStm32UsartState *s)
{
    uint32_t sr = s->regs[R_SR], cr1 = s->regs[R_CR1], cr3 = s->regs[R_CR3];
    bool irq = ((cr1 & CR1_TXEIE) && (sr & SR_TXE)) || ((cr1 & CR1_TCIE) && (sr & SR_TC)) ||
               ((cr1 & CR1_RXNEIE) && (sr & (SR_RXNE | SR_ORE))) || ((cr1 & CR1_IDLEIE) && (sr & SR_IDLE)) ||
               ((cr1 & CR1_PEIE) && (sr & SR_PE)) ||
               ((cr3 & CR3_EIE) && (cr3 & CR3_DMAR) && (sr & (SR_FE | SR_ORE | SR_NF))) ||
               ((s->regs[R_CR2] & CR2_LBDIE) && (sr & SR_LBD)) || ((cr3 & CR3_CTSIE) && (sr & SR_CTS));
    qemu_set_irq(s->irq, irq);
    bool dma[2] = { (cr3 & CR3_DMAR) && (sr & SR_RXNE), (cr3 & CR3_DMAT) && (sr & SR_TXE) };
    for (unsigned k = 0; k < 2; k++) {
        if (dma[k] != s->dma_level[k]) {
            s->dma_level[k] = dma[k];
            qemu_set_irq(s->dma[k], dma[k]);
        }
    }
}

/* DR read (@k 0) or written (1), by the DMA or the core: the request is down until RXNE or TXE comes again
 * (a request is a level the DMA serves once a rise) */
static void dma_served(RigStm32UsartState *s, unsigned k)
{
    if (s->dma_level[k]) {
        s->dma_level[k] = false;
        qemu_set_irq(s->dma[k], 0);
    }
}

/* The transmitter: the next frame starts at @at_ns if a byte waits and TE and UE allow */
static void tx_next(RigStm32UsartState *s, int64_t at_ns)
{
    uint32_t cr1 = s->regs[R_CR1];
    s->tx_busy = false;
    if (!(s->regs[R_SR] & SR_TXE) && (cr1 & CR1_TE) && (cr1 & CR1_UE)) {
        s->tx_byte = (uint8_t)s->tdr;
        s->tx_idle_frame = false;
        s->tx_busy = true;
        s->tx_end_ns = at_ns + bit_ns(s, frame_sixteenths(s));
        s->regs[R_SR] |= SR_TXE;
    } else if (s->regs[R_SR] & SR_TXE) {
        s->regs[R_SR] |= SR_TC;
    }
}

static void tx_catch_up(RigStm32UsartState *s, int64_t now)
{
    while (s->tx_busy && s->tx_end_ns <= now) {
        if (!s->tx_idle_frame && qemu_chr_fe_backend_connected(&s->chr)) {
            qemu_chr_fe_write_all(&s->chr, &s->tx_byte, 1);
        }
        if (!s->tx_idle_frame && s->trace_bytes) {
            fprintf(stderr, "rig-stm32f4-usart: t_ns=%" PRId64 " USART%u byte=0x%02x\n", s->tx_end_ns, s->index,
                    s->tx_byte);
        }
        tx_next(s, s->tx_end_ns);
        rig_usart_update_irqs(s); /* (with DMAT the DMA fills DR at this instant, before the next frame) */
    }
}

/* The instant the transmitter needs its QEMU timer for (INT64_MAX: none). Each frame's end while TXEIE,
 * TCIE or DMAT may want it; but with DMAT and the stream feeding it enabled (memory-to-peripheral, neither
 * circular nor double-buffer) every byte's frame is known ahead: the DMA fills DR at each TXE, so with DR
 * full now (the shift register sending until tx_end) the k-th item left is transferred at tx_end + (k - 1)
 * frames and leaves the line at tx_end + (k + 1) frames. Then only the instant an interrupt is due needs
 * the timer: the stream's HTIF or TCIF (with HTIE, TCIE) or the USART's TC (with TCIE); the bytes between
 * go out when the firmware next touches the USART or the DMA, or the link reaches a time (catch_up), at the
 * instants they would have. (A transfer error, a bus error reading memory, shows at that catch-up; the
 * memory is read then too, and the frame's time is the one PCLK gives then.) With DMAT and no stream
 * serving it, nothing but TCIE needs the frame's end: a stream enabled later first brings the USART up to
 * now (rig_stm32_dma_add_sync) and takes the request then. */
static int64_t tx_deadline(RigStm32UsartState *s)
{
    uint32_t cr1 = s->regs[R_CR1], cr, ndtr, reload;
    if (!s->tx_busy) {
        return INT64_MAX;
    }
    if ((cr1 & CR1_TXEIE) || ((s->regs[R_CR3] & CR3_DMAT) && s->dma_ctl == NULL)) {
        return s->tx_end_ns;
    }
    if (!(s->regs[R_CR3] & CR3_DMAT) ||
        !rig_stm32_dma_request_stream(s->dma_ctl, RIG_DMA_USART_TX(s->index), &cr, &ndtr, &reload)) {
        /* TC: when the shift register is done with nothing in DR, or with the byte in DR sent too */
        int64_t last = s->tx_end_ns + ((s->regs[R_SR] & SR_TXE) ? 0 : bit_ns(s, frame_sixteenths(s)));
        return (cr1 & CR1_TCIE) ? last : INT64_MAX;
    }
    if ((s->regs[R_SR] & SR_TXE) || (cr1 & (CR1_UE | CR1_TE)) != (CR1_UE | CR1_TE) ||
        (cr & DMA_CR_DIR_MASK) != DMA_CR_DIR_M2P || (cr & (DMA_CR_CIRC | DMA_CR_DBM))) {
        return s->tx_end_ns;
    }
    int64_t frame = bit_ns(s, frame_sixteenths(s)), when = INT64_MAX;
    uint32_t done = reload - ndtr, half = (reload + 1) / 2; /* (HTIF: the first item with 2 x done >= reload) */
    if (cr & DMA_CR_TCIE) {
        when = s->tx_end_ns + (int64_t)(ndtr - 1) * frame;
    }
    if ((cr & DMA_CR_HTIE) && done < half) {
        when = MIN(when, s->tx_end_ns + (int64_t)(half - done - 1) * frame);
    }
    if (cr1 & CR1_TCIE) {
        when = MIN(when, s->tx_end_ns + (int64_t)(ndtr + 1) * frame);
    }
    return when;
}

/* The QEMU timer only when an interrupt or DMA request may follow the next event */
static void arm(RigStm32UsartState *s)
{
    if (s->catching_up) {
        return; /* (a DMA access inside catch_up: the caller arms once it is done) */
    }
    int64_t when = MIN(tx_deadline(s), rig_usart_rx_deadline(s));
    if (when == INT64_MAX) {
        timer_del(s->timer);
    } else if (!timer_pending(s->timer) || timer_expire_time_ns(s->timer) != when) {
        timer_mod(s->timer, when); /* (a timer moved to the front of the list wakes the main loop) */
    }
}

static void catch_up(RigStm32UsartState *s)
{
    if (s->catching_up) {
        return;
    }
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    s->catching_up = true;
    tx_catch_up(s, now);
    rig_usart_rx_catch_up(s, now);
    s->catching_up = false;
}

static void usart_tick(void *opaque)
{
    RigStm32UsartState *s = opaque;
    catch_up(s);
    rig_usart_update_irqs(s);
    arm(s);
}

/* The link's sync: every USART up to now before a time is reached (its bytes sent in the chardev) */
#define USARTS 6
static RigStm32UsartState *usarts[USARTS];
static unsigned n_usarts;

static void usarts_sync(void *opaque)
{
    for (unsigned i = 0; i < n_usarts; i++) {
        usart_tick(usarts[i]);
    }
}

bool rig_stm32_usart_receive(DeviceState *dev, uint8_t byte, int64_t start_ns, uint32_t baud, char parity,
                             unsigned stop_bits)
{
    RigStm32UsartState *s = RIG_STM32_USART(dev);
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    catch_up(s);
    if (s->n_frames == FRAMES) {
        return false;
    }
    UsartFrame *f = &s->frames[(s->frame_head + s->n_frames++) % FRAMES];
    unsigned n = 1 + 8;
    f->bits = (uint16_t)byte << 1; /* the start bit low, then the data bits, LSB first */
    if (parity == 'E' || parity == 'O') {
        f->bits |= (uint16_t)((ctpop8(byte) & 1) ^ (parity == 'O')) << n++;
    }
    for (unsigned i = 0; i < stop_bits; i++) {
        f->bits |= 1u << n++;
    }
    f->n_bits = (uint8_t)n;
    f->baud = MAX(baud, 1);
    f->start_ns = MAX(MAX(start_ns, now), s->line_end_ns);
    f->end_ns = f->start_ns + (int64_t)(((uint64_t)n * NS + f->baud - 1) / f->baud);
    s->line_end_ns = f->start_ns + (int64_t)muldiv64(n, NS, f->baud);
    rig_usart_update_irqs(s);
    arm(s);
    return true;
}

static uint64_t usart_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32UsartState *s = opaque;
    uint64_t value = 0;
    if (!usart_clocked(s)) {
        return 0;
    }
    catch_up(s);
    switch (rig_register_index(s->table, R_COUNT, offset)) {
    case R_SR:
        s->sr_seen = s->regs[R_SR];
        value = s->regs[R_SR];
        break;
    case R_DR:
        value = s->regs[R_DR] & ((s->regs[R_CR1] & CR1_M) ? 0x1FF : 0xFF);
        s->regs[R_SR] &= ~(SR_RXNE | (s->sr_seen & SR_READ_CLEARED));
        s->sr_seen &= ~SR_READ_CLEARED;
        dma_served(s, 0);
        break;
    case R_BRR:
    case R_CR1:
    case R_CR2:
    case R_CR3:
    case R_GTPR:
        value = s->regs[rig_register_index(s->table, R_COUNT, offset)];
        break;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-usart: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    rig_usart_update_irqs(s);
    arm(s);
    return value;
}

static void write_dr(RigStm32UsartState *s, uint32_t value)
{
    if (s->sr_seen & SR_TC) { /* TC's clear sequence: SR read, then DR written */
        s->regs[R_SR] &= ~SR_TC;
        s->sr_seen &= ~SR_TC;
    }
    if (!(s->regs[R_SR] & SR_TXE)) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-usart: DR written while TXE = 0: the waiting byte is lost\n");
    }
    s->tdr = (uint16_t)(value & 0x1FF);
    s->regs[R_SR] &= ~SR_TXE;
    dma_served(s, 1);
    if (!s->tx_busy) {
        tx_next(s, qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL));
    }
}

static void write_cr1(RigStm32UsartState *s, uint32_t value)
{
    bool te_was = (s->regs[R_CR1] & (CR1_TE | CR1_UE)) == (CR1_TE | CR1_UE);
    bool rx_was = (s->regs[R_CR1] & (CR1_RE | CR1_UE)) == (CR1_RE | CR1_UE);
    s->regs[R_CR1] = value & s->table[R_CR1].writable & ~CR1_SBK; /* no break on the wire */
    bool te_now = (s->regs[R_CR1] & (CR1_TE | CR1_UE)) == (CR1_TE | CR1_UE);
    bool rx_now = (s->regs[R_CR1] & (CR1_RE | CR1_UE)) == (CR1_RE | CR1_UE);
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    if (!rx_was && rx_now) {
        s->rx.pos_ns = now; /* the receiver looks for a start bit from now on */
    }
    if (!te_was && te_now && !s->tx_busy) { /* 30.3.2: TE set sends an idle frame (the preamble) first */
        s->tx_busy = s->tx_idle_frame = true;
        s->tx_end_ns = now + bit_ns(s, frame_sixteenths(s));
    }
}

static void usart_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32UsartState *s = opaque;
    uint32_t v = (uint32_t)value;
    if (!usart_clocked(s)) {
        return;
    }
    catch_up(s);
    int index = rig_register_index(s->table, R_COUNT, offset);
    switch (index) {
    case R_SR: /* rc_w0: writing 0 clears, 1 leaves */
        s->regs[R_SR] &= v | ~s->table[R_SR].writable;
        break;
    case R_DR:
        write_dr(s, v);
        break;
    case R_CR1:
        write_cr1(s, v);
        break;
    case R_BRR:
    case R_CR2:
    case R_CR3:
    case R_GTPR:
        s->regs[index] = v & s->table[index].writable;
        break;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-usart: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    rig_usart_update_irqs(s);
    arm(s);
}

static const MemoryRegionOps usart_ops = {
    .read = usart_read,
    .write = usart_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .valid.min_access_size = 1,
    .valid.max_access_size = 4,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void usart_reset(DeviceState *dev)
{
    RigStm32UsartState *s = RIG_STM32_USART(dev);
    timer_del(s->timer);
    for (unsigned i = 0; i < R_COUNT; i++) {
        s->regs[i] = s->table[i].reset;
    }
    s->sr_seen = 0;
    s->tdr = 0;
    s->tx_busy = s->tx_idle_frame = s->rx.idle_armed = false;
    s->catching_up = false;
    /* (the sender's frames stay: the line is outside the chip; those before now go unseen) */
    s->rx.pos_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    rig_usart_update_irqs(s);
}

static void usart_realize(DeviceState *dev, Error **errp)
{
    RigStm32UsartState *s = RIG_STM32_USART(dev);
    s->table = s->uart ? uart_registers : usart_registers;
    if (n_usarts == 0) {
        rig_link_sync_add(usarts_sync, NULL);
    }
    if (n_usarts == USARTS) {
        error_setg(errp, "rig-stm32f4-usart: more than %d USARTs", USARTS);
        return;
    }
    usarts[n_usarts++] = s;
    if (s->dma_ctl != NULL) {
        rig_stm32_dma_add_sync(s->dma_ctl, usart_tick, s);
    }
}

static void usart_init(Object *obj)
{
    RigStm32UsartState *s = RIG_STM32_USART(obj);
    memory_region_init_io(&s->iomem, obj, &usart_ops, s, TYPE_RIG_STM32_USART, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq);
    qdev_init_gpio_out_named(DEVICE(obj), &s->dma[0], "dma-rx", 1);
    qdev_init_gpio_out_named(DEVICE(obj), &s->dma[1], "dma-tx", 1);
    s->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, usart_tick, s);
    s->table = usart_registers;
}

static Property usart_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32UsartState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_LINK("dma", RigStm32UsartState, dma_ctl, TYPE_RIG_STM32_DMA, RigStm32DmaState *),
    DEFINE_PROP_CHR("chardev", RigStm32UsartState, chr),
    DEFINE_PROP_UINT8("apb", RigStm32UsartState, apb, 2),
    DEFINE_PROP_UINT8("rcc-bit", RigStm32UsartState, rcc_bit, 4),
    DEFINE_PROP_BOOL("uart", RigStm32UsartState, uart, false),
    DEFINE_PROP_UINT8("index", RigStm32UsartState, index, 0),
    DEFINE_PROP_BOOL("trace-bytes", RigStm32UsartState, trace_bytes, false),
    DEFINE_PROP_END_OF_LIST(),
};

static void usart_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->realize = usart_realize;
    dc->reset = usart_reset;
    device_class_set_props(dc, usart_properties);
}

static const TypeInfo usart_info = {
    .name = TYPE_RIG_STM32_USART,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32UsartState),
    .instance_init = usart_init,
    .class_init = usart_class_init,
};

static void usart_register_types(void) { type_register_static(&usart_info); }

type_init(usart_register_types)
