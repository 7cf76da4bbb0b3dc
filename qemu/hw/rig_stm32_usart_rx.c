/*
 * The STM32F4 USART's receiver (rig_stm32_usart.c has the rest): the line as the sender's frames make it,
 * read as the chip reads it (RM0090 30.3.3), in virtual time, lazily.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "qemu/timer.h"
#include "rig_stm32_usart.h"

/* The level of the line at @t (idle, high, outside the sender's frames) */
static bool line_level(const RigStm32UsartState *s, int64_t t)
{
    for (unsigned i = 0; i < s->n_frames; i++) {
        const UsartFrame *f = &s->frames[(s->frame_head + i) % FRAMES];
        if (t < f->start_ns) {
            break;
        }
        if (t >= f->end_ns) {
            continue;
        }
        /* (within the frame, (t - start) x baud < (n_bits x NS / baud + 1) x baud: no overflow) */
        uint64_t bit = (uint64_t)(t - f->start_ns) * f->baud / NS;
        if (bit < f->n_bits) {
            return f->bits >> bit & 1;
        }
    }
    return true;
}

/* The first falling edge of the line at or after @from, or INT64_MAX */
static int64_t next_falling_edge(const RigStm32UsartState *s, int64_t from)
{
    for (unsigned i = 0; i < s->n_frames; i++) {
        const UsartFrame *f = &s->frames[(s->frame_head + i) % FRAMES];
        for (unsigned b = 0; b < f->n_bits; b++) {
            if ((f->bits >> b & 1) || (b > 0 && !(f->bits >> (b - 1) & 1))) {
                continue;
            }
            int64_t edge = f->start_ns + (int64_t)((b * NS + f->baud - 1) / f->baud);
            if (edge >= from) {
                return edge;
            }
        }
    }
    return INT64_MAX;
}

/* The receiver's bit clock while it reads a frame: PCLK ticks per bit and PCLK (bit_ns's, taken once) */
typedef struct {
    uint64_t ticks, pclk_hz;
} RxClock;

/* Bit @k of a frame starting at @start as the receiver samples it (30.3.3: samples 8, 9 and 10 of 16,
 * or 4, 5 and 6 of 8 with OVER8, the majority taken; ONEBIT: the middle one); *noisy when they differ */
static bool sample_bit(const RigStm32UsartState *s, const RxClock *clk, int64_t start, unsigned k, bool *noisy)
{
    static const unsigned over16[3] = { 7, 8, 9 }, over8[3] = { 6, 8, 10 };
    const unsigned *at = (s->regs[R_CR1] & CR1_OVER8) ? over8 : over16;
    if (s->regs[R_CR3] & CR3_ONEBIT) {
        return line_level(s, start + sixteenths_ns(k * SIXTEENTHS + 8, clk->ticks, clk->pclk_hz));
    }
    unsigned ones = 0;
    for (unsigned i = 0; i < 3; i++) {
        ones += line_level(s, start + sixteenths_ns(k * SIXTEENTHS + at[i], clk->ticks, clk->pclk_hz));
    }
    *noisy |= ones == 1 || ones == 2;
    return ones >= 2;
}

/* What the receiver at @c sees next: a frame (its data and error flags at *at, the stop bit's middle) or
 * IDLE (flags SR_IDLE); false when the line stays idle. The line after the sender's last frame is idle: a
 * frame given later starts after now, and makes the next look again. */
static bool rx_next(const RigStm32UsartState *s, const RigUsartRxCursor *c, int64_t *at, uint16_t *data,
                    uint32_t *flags)
{
    int64_t idle_at = c->idle_armed ? c->idle_from_ns + bit_ns(s, frame_sixteenths(s)) : INT64_MAX;
    const RxClock clk = { ticks_per_bit(s), pclk_hz(s) };
    for (int64_t from = c->pos_ns;;) {
        int64_t edge = next_falling_edge(s, from);
        if (edge == INT64_MAX || edge >= idle_at) {
            *at = idle_at;
            *flags = SR_IDLE;
            return idle_at != INT64_MAX;
        }
        bool noisy = false;
        if (sample_bit(s, &clk, edge, 0, &noisy)) {
            from = edge + 1; /* no start bit: a glitch (or the sender's bits out of step) */
            continue;
        }
        unsigned n = data_bits(s), ones = 0;
        *data = 0;
        for (unsigned k = 0; k < n; k++) {
            bool bit = sample_bit(s, &clk, edge, 1 + k, &noisy);
            *data |= (uint16_t)bit << k;
            ones += bit;
        }
        bool stop = sample_bit(s, &clk, edge, 1 + n, &noisy);
        *flags = (stop ? 0 : SR_FE) | (noisy && !(s->regs[R_CR3] & CR3_ONEBIT) ? SR_NF : 0);
        /* 30.3.7: even parity (PS = 0) makes the ones of the data and parity bits even, odd makes them odd */
        if ((s->regs[R_CR1] & CR1_PCE) && (ones & 1) != !!(s->regs[R_CR1] & CR1_PS)) {
            *flags |= SR_PE;
        }
        *at = edge + sixteenths_ns((1 + n) * SIXTEENTHS + 8, clk.ticks, clk.pclk_hz);
        return true;
    }
}

/* The receiver at @c past the event rx_next gave (at @at, @flags) */
static void rx_step(const RigStm32UsartState *s, RigUsartRxCursor *c, int64_t at, uint32_t flags)
{
    if (flags == SR_IDLE) {
        c->idle_armed = false;
        return;
    }
    c->pos_ns = at;
    c->idle_armed = true;
    c->idle_from_ns = at + bit_ns(s, frame_sixteenths(s) - (1 + data_bits(s)) * SIXTEENTHS - 8);
}

void rig_usart_rx_catch_up(RigStm32UsartState *s, int64_t now)
{
    uint32_t cr1 = s->regs[R_CR1];
    if (!(cr1 & CR1_RE) || !(cr1 & CR1_UE)) { /* the receiver is off: what passes is not seen */
        s->rx.pos_ns = MAX(s->rx.pos_ns, now);
        s->rx.idle_armed = false;
    }
    int64_t at;
    uint16_t data;
    uint32_t flags;
    while (rx_next(s, &s->rx, &at, &data, &flags) && at <= now) {
        rx_step(s, &s->rx, at, flags);
        if (flags == SR_IDLE) {
            s->regs[R_SR] |= SR_IDLE;
            continue;
        }
        if (s->regs[R_SR] & SR_RXNE) {
            s->regs[R_SR] |= SR_ORE; /* 30.6.1: the new byte is lost, DR keeps the one before */
        } else {
            s->regs[R_DR] = data;
            s->regs[R_SR] = (s->regs[R_SR] & ~(SR_PE | SR_FE | SR_NF)) | flags | SR_RXNE;
        }
        rig_usart_update_irqs(s); /* (with DMAR the DMA takes DR at this instant, before the next byte) */
    }
    /* frames the receiver is done with */
    while (s->n_frames) {
        const UsartFrame *f = &s->frames[s->frame_head];
        if (f->start_ns + (int64_t)muldiv64(f->n_bits, NS, f->baud) > MIN(s->rx.pos_ns, now)) {
            break;
        }
        s->frame_head = (s->frame_head + 1) % FRAMES;
        s->n_frames--;
    }
}

/* Each event while an interrupt or a DMA request may follow it; but with DMAR, RXNEIE clear and the stream
 * on the USART's RX request enabled (peripheral-to-memory), the DMA takes each byte from DR as it comes
 * (RXNE never stays set), so the bytes need no instant of their own: they go into the DMA when the
 * firmware next touches the USART or the DMA, or the link reaches a time (catch_up), each as it would
 * have, with the same flags. Only an interrupt's instant needs the timer: IDLE (IDLEIE), the byte that
 * sets PE (PEIE) or FE/NF (EIE), the stream's HTIF or TCIF (HTIE, TCIE), or the stream's last item when
 * it does not wrap (the eager path after it). The memory is written at that catch-up: a firmware polling
 * the buffer with no register access sees its bytes late (one reading NDTR sees them in time); a bus
 * error writing memory (TEIF) shows then too. */
#define RX_LOOKAHEAD 256 /* bytes looked at ahead at most (a long burst: the timer looks again there) */

int64_t rig_usart_rx_deadline(RigStm32UsartState *s)
{
    uint32_t cr1 = s->regs[R_CR1], cr3 = s->regs[R_CR3], cr, ndtr, reload, flags;
    int64_t at;
    uint16_t data;
    if (!(cr1 & (CR1_RXNEIE | CR1_IDLEIE | CR1_PEIE)) && !(cr3 & (CR3_DMAR | CR3_EIE))) {
        return INT64_MAX;
    }
    if (!rx_next(s, &s->rx, &at, &data, &flags)) {
        return INT64_MAX;
    }
    if ((cr1 & CR1_RXNEIE) || !(cr3 & CR3_DMAR) || (s->regs[R_SR] & SR_RXNE) || s->dma_ctl == NULL ||
        (cr1 & (CR1_UE | CR1_RE)) != (CR1_UE | CR1_RE) ||
        !rig_stm32_dma_request_stream(s->dma_ctl, RIG_DMA_USART_RX(s->index), &cr, &ndtr, &reload) ||
        (cr & DMA_CR_DIR_MASK) != DMA_CR_DIR_P2M) {
        return at;
    }
    uint32_t done = reload - ndtr, half = (reload + 1) / 2, left = UINT32_MAX; /* HTIF: as the DMA sets it */
    if ((cr & DMA_CR_TCIE) || !(cr & (DMA_CR_CIRC | DMA_CR_DBM))) {
        left = ndtr;
    }
    if (cr & DMA_CR_HTIE) {
        left = MIN(left, done < half ? half - done : ndtr + half);
    }
    RigUsartRxCursor c = s->rx;
    for (uint32_t bytes = 0;;) {
        if (flags == SR_IDLE) {
            if (cr1 & CR1_IDLEIE) {
                return at;
            }
        } else if (++bytes == MIN(left, RX_LOOKAHEAD) || ((cr1 & CR1_PEIE) && (flags & SR_PE)) ||
                   ((cr3 & CR3_EIE) && (flags & (SR_FE | SR_NF)))) {
            return at;
        }
        rx_step(s, &c, at, flags);
        if (!rx_next(s, &c, &at, &data, &flags)) {
            return INT64_MAX;
        }
    }
}
