/*
 * The STM32F405's DMA controllers DMA1 and DMA2, RM0090 section 10: one model, the registers a table of
 * data (10.5): LISR/HISR, LIFCR/HIFCR (write 1 to clear), and per stream SxCR, SxNDTR, SxPAR, SxM0AR,
 * SxM1AR and SxFCR with their reset values; the configuration is read-only while the stream is enabled
 * (writes to it are ignored and logged), EN reads 0 once a transfer completes.
 *
 * Transfers: peripheral-to-memory and memory-to-peripheral on the requests of the channel CHSEL selects
 * (RM0090 tables 42 and 43, the request mapping, as data below: the requests of the peripherals that are
 * modelled, the timers, I2C1, the USARTs and the ADCs), one data item (PSIZE) per request at the virtual instant
 * of the request; memory-to-memory (DMA2 only) all at once when the stream is enabled. Items move through
 * QEMU's system address space with the PSIZE and MSIZE widths, the addresses incrementing by PINC
 * (PINCOS: by 4) and MINC; NDTR counts down; circular mode starts again from the NDTR written; double-buffer mode
 * switches CT at each end. FIFO mode is stored and moves the items as direct mode does, packing when
 * PSIZE and MSIZE differ; no FIFO or direct-mode error arises (FEIF and DMEIF stay clear). Flags: HTIF at
 * half the items, TCIF at the end (or when software disables a stream under way), TEIF on a bus error
 * (an address nothing answers: the stream is disabled), each with its enable to the stream's interrupt
 * line. The registers answer, and requests are served, only with the controller's clock enabled
 * (RCC_AHB1ENR.DMA1EN, DMA2EN); RCC_AHB1RSTR resets it.
 *
 * Requests are levels ("request" inputs, numbered as RIG_DMA_TIMER, RIG_DMA_I2C1_RX/TX and
 * RIG_DMA_USART_RX/TX): each raise moves one item on the stream whose CHSEL selects it (the timers pulse
 * theirs; I2C1 and the USARTs lower their own when the DMA takes or fills DR); a request raised while an
 * item is moving (its access to the peripheral raised it) is served after. A stream enabled while its
 * request is up is served at once. "eot1" outputs pulse when the last-but-one item of a transfer is taken
 * (the EOT_1 signal I2C's CR2.LAST uses to NACK the last byte, RM0090 27.3.8).
 *
 * Not modelled: bursts (PBURST/MBURST move single items), priorities (requests are served at once, so
 * streams never wait on each other), the FIFO's threshold and errors, peripheral flow control (PFCTRL
 * stored), the DMA1 peripheral port's limit to APB1 (but for memory-to-memory on DMA1: a transfer error).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "exec/address-spaces.h"
#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"

#define AHB1ENR 0x30
#define AHB1ENR_DMA1EN 21 /* DMA2EN: 22 */
/* the DMA requests served at one virtual instant before the rest wait for the next microsecond (about the
 * pace of the chip's AHB, a few cycles an item) */
#define RIG_DMA_ROUNDS_AT_ONCE 16
#define RIG_DMA_PACE_NS 1000

/* RM0090 10.5.1-10.5.4 (table 44, the DMA register map): the interrupt status and clear registers */
static const RigRegister dma_registers[] = {
    { 0x00, "LISR", 0x00000000, 0x00000000 },  /* read only */
    { 0x04, "HISR", 0x00000000, 0x00000000 },  /* read only */
    { 0x08, "LIFCR", 0x00000000, 0x0F7D0F7D }, /* write 1 to clear; reads 0 */
    { 0x0C, "HIFCR", 0x00000000, 0x0F7D0F7D },
};
enum { R_LISR, R_HISR, R_LIFCR, R_HIFCR };
#define STREAM_BASE 0x10
#define STREAM_STRIDE 0x18

/* RM0090 10.5.5-10.5.10: a stream's registers at 0x10 + 0x18 x stream, and the bits writable while EN is
 * set (the interrupt enables and EN; FCR's FEIE; M0AR and M1AR in double-buffer mode when not the
 * current target, handled below) */
static const struct {
    RigRegister reg;
    uint32_t writable_enabled;
} stream_registers[] = {
    { { 0x00, "SxCR", 0x00000000, 0x0FEFFFFF }, 0x0000001F }, /* EN ... CHSEL (bit 20 reserved) */
    { { 0x04, "SxNDTR", 0x00000000, 0x0000FFFF }, 0 },         { { 0x08, "SxPAR", 0x00000000, 0xFFFFFFFF }, 0 },
    { { 0x0C, "SxM0AR", 0x00000000, 0xFFFFFFFF }, 0 },         { { 0x10, "SxM1AR", 0x00000000, 0xFFFFFFFF }, 0 },
    { { 0x14, "SxFCR", 0x00000021, 0x00000087 }, 0x00000080 }, /* FTH, DMDIS, FEIE; FS read only (100: empty) */
};
enum { S_CR, S_NDTR, S_PAR, S_M0AR, S_M1AR, S_FCR, S_REGS };

#define CR_EN (1u << 0)
#define CR_DMEIE (1u << 1)
#define CR_TEIE (1u << 2)
#define CR_HTIE (1u << 3)
#define CR_TCIE (1u << 4)
#define CR_DIR_SHIFT 6
#define DIR_P2M 0
#define DIR_M2P 1
#define DIR_M2M 2
#define CR_CIRC (1u << 8)
#define CR_PINC (1u << 9)
#define CR_MINC (1u << 10)
#define CR_PSIZE_SHIFT 11
#define CR_MSIZE_SHIFT 13
#define CR_PINCOS (1u << 15)
#define CR_DBM (1u << 18)
#define CR_CT (1u << 19)
#define CR_CHSEL_SHIFT 25
#define FCR_DMDIS (1u << 2)
#define FCR_FEIE (1u << 7)
/* a stream's flags in LISR/HISR, from its bit 0 there (10.5.1) */
#define FEIF (1u << 0)
#define DMEIF (1u << 2)
#define TEIF (1u << 3)
#define HTIF (1u << 4)
#define TCIF (1u << 5)
static const uint8_t flag_shift[4] = { 0, 6, 16, 22 }; /* streams 0-3 in LISR, 4-7 in HISR */

/* RM0090 table 42 (DMA1) and table 43 (DMA2) request mapping: the requests of the modelled peripherals,
 * each on a stream and channel (several requests on one, as TIM2_UP/TIM2_CH3, are ORed); the USARTs' are
 * channel 4 of DMA1 (USART2, USART3, UART4, UART5; USART3_TX also on stream 4 channel 7) and channels 4
 * and 5 of DMA2 (USART1, USART6). The F411's (RM0383 tables 27 and 28) are the same for what it has of
 * these: its timers, I2C1, USART1, USART2 and USART6 */
#define T(n, r) RIG_DMA_TIMER(n, RIG_DMA_##r)
#define U_RX(n) RIG_DMA_USART_RX(n)
#define U_TX(n) RIG_DMA_USART_TX(n)
#define ADC(n) RIG_DMA_ADC(n)
static const struct {
    uint8_t dma, stream, channel;
    uint8_t source;
} request_map[] = {
    { 1, 0, 1, RIG_DMA_I2C1_RX }, { 1, 0, 2, T(4, CC1) },  { 1, 0, 6, T(5, CC3) },  { 1, 0, 6, T(5, UP) },
    { 1, 1, 3, T(2, UP) },        { 1, 1, 3, T(2, CC3) },  { 1, 1, 6, T(5, CC4) },  { 1, 1, 6, T(5, TRIG) },
    { 1, 1, 7, T(6, UP) },        { 1, 2, 1, T(7, UP) },   { 1, 2, 5, T(3, CC4) },  { 1, 2, 5, T(3, UP) },
    { 1, 2, 6, T(5, CC1) },       { 1, 3, 2, T(4, CC2) },  { 1, 3, 6, T(5, CC4) },  { 1, 3, 6, T(5, TRIG) },
    { 1, 4, 1, T(7, UP) },        { 1, 4, 5, T(3, CC1) },  { 1, 4, 5, T(3, TRIG) }, { 1, 4, 6, T(5, CC2) },
    { 1, 5, 1, RIG_DMA_I2C1_RX }, { 1, 5, 3, T(2, CC1) },  { 1, 5, 5, T(3, CC2) },  { 1, 6, 1, RIG_DMA_I2C1_TX },
    { 1, 6, 2, T(4, UP) },        { 1, 6, 3, T(2, CC2) },  { 1, 6, 3, T(2, CC4) },  { 1, 6, 6, T(5, UP) },
    { 1, 7, 1, RIG_DMA_I2C1_TX }, { 1, 7, 2, T(4, CC3) },  { 1, 7, 3, T(2, UP) },   { 1, 7, 3, T(2, CC4) },
    { 1, 7, 5, T(3, CC3) },       { 2, 0, 6, T(1, TRIG) }, { 2, 1, 6, T(1, CC1) },  { 2, 1, 7, T(8, UP) },
    { 2, 2, 0, T(8, CC1) },       { 2, 2, 0, T(8, CC2) },  { 2, 2, 0, T(8, CC3) },  { 2, 2, 6, T(1, CC2) },
    { 2, 2, 7, T(8, CC1) },       { 2, 3, 6, T(1, CC1) },  { 2, 3, 7, T(8, CC2) },  { 2, 4, 6, T(1, CC4) },
    { 2, 4, 6, T(1, TRIG) },      { 2, 4, 6, T(1, COM) },  { 2, 4, 7, T(8, CC3) },  { 2, 5, 6, T(1, UP) },
    { 2, 6, 0, T(1, CC1) },       { 2, 6, 0, T(1, CC2) },  { 2, 6, 0, T(1, CC3) },  { 2, 6, 6, T(1, CC3) },
    { 2, 7, 7, T(8, CC4) },       { 2, 7, 7, T(8, TRIG) }, { 2, 7, 7, T(8, COM) },  { 1, 0, 4, U_RX(5) },
    { 1, 1, 4, U_RX(3) },         { 1, 2, 4, U_RX(4) },    { 1, 3, 4, U_TX(3) },    { 1, 4, 4, U_TX(4) },
    { 1, 4, 7, U_TX(3) },         { 1, 5, 4, U_RX(2) },    { 1, 6, 4, U_TX(2) },    { 1, 7, 4, U_TX(5) },
    { 2, 2, 4, U_RX(1) },         { 2, 5, 4, U_RX(1) },    { 2, 7, 4, U_TX(1) },    { 2, 1, 5, U_RX(6) },
    { 2, 2, 5, U_RX(6) },         { 2, 6, 5, U_TX(6) },    { 2, 7, 5, U_TX(6) },    { 2, 0, 0, ADC(1) },
    { 2, 4, 0, ADC(1) },          { 2, 2, 1, ADC(2) },     { 2, 3, 1, ADC(2) },     { 2, 0, 2, ADC(3) },
    { 2, 1, 2, ADC(3) },
};
#undef T
#undef U_RX
#undef U_TX
#undef ADC

static bool dma_clocked(RigStm32DmaState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, AHB1ENR, AHB1ENR_DMA1EN + s->controller - 1);
}

static unsigned direction(const RigDmaStream *st) { return st->cr >> CR_DIR_SHIFT & 3; }
static unsigned item_bytes(uint32_t cr, unsigned shift) { return 1u << MIN(cr >> shift & 3, 2u); }

static uint32_t flags(const RigStm32DmaState *s, unsigned n) { return s->isr[n / 4] >> flag_shift[n % 4] & 0x3D; }
static void set_flags(RigStm32DmaState *s, unsigned n, uint32_t f) { s->isr[n / 4] |= f << flag_shift[n % 4]; }

static void update_irqs(RigStm32DmaState *s)
{
    for (unsigned n = 0; n < RIG_DMA_STREAMS; n++) {
        const RigDmaStream *st = &s->stream[n];
        uint32_t f = flags(s, n), cr = st->cr;
        bool on = ((f & TCIF) && (cr & CR_TCIE)) || ((f & HTIF) && (cr & CR_HTIE)) || ((f & TEIF) && (cr & CR_TEIE)) ||
                  ((f & DMEIF) && (cr & CR_DMEIE)) || ((f & FEIF) && (st->fcr & FCR_FEIE));
        qemu_set_irq(s->irq[n], on);
    }
}

/* The address a memory access of this round goes to: M0AR or M1AR (CT in double-buffer mode) */
static hwaddr memory_address(const RigDmaStream *st)
{
    return ((st->cr & CR_DBM) && (st->cr & CR_CT) ? st->m1ar : st->m0ar) + st->m_off;
}

static bool bus_read(hwaddr addr, uint8_t *buf, unsigned len)
{
    return address_space_read(&address_space_memory, addr, MEMTXATTRS_UNSPECIFIED, buf, len) == MEMTX_OK;
}

static bool bus_write(hwaddr addr, const uint8_t *buf, unsigned len)
{
    return address_space_write(&address_space_memory, addr, MEMTXATTRS_UNSPECIFIED, buf, len) == MEMTX_OK;
}

/* Writes what the FIFO holds to memory, MSIZE at a time (@all: the rest too, a byte at a time) */
static bool drain_to_memory(RigDmaStream *st, bool all)
{
    unsigned msize = item_bytes(st->cr, CR_MSIZE_SHIFT), done = 0;
    while (st->fifo_len - done >= msize || (all && st->fifo_len > done)) {
        unsigned len = st->fifo_len - done >= msize ? msize : 1;
        if (!bus_write(memory_address(st), st->fifo + done, len)) {
            return false;
        }
        done += len;
        st->m_off += (st->cr & CR_MINC) ? len : 0;
    }
    memmove(st->fifo, st->fifo + done, st->fifo_len - done);
    st->fifo_len -= done;
    return true;
}

/* One data item (PSIZE bytes at the peripheral port, PAR): false on a bus error */
static bool move_item(RigDmaStream *st)
{
    unsigned psize = item_bytes(st->cr, CR_PSIZE_SHIFT), msize = item_bytes(st->cr, CR_MSIZE_SHIFT);
    hwaddr paddr = st->par + st->p_off;
    bool ok = true;
    if (direction(st) == DIR_M2P) {
        while (st->fifo_len < psize) {
            if (!bus_read(memory_address(st), st->fifo + st->fifo_len, msize)) {
                return false;
            }
            st->fifo_len += msize;
            st->m_off += (st->cr & CR_MINC) ? msize : 0;
        }
        ok = bus_write(paddr, st->fifo, psize);
        st->fifo_len -= psize;
        memmove(st->fifo, st->fifo + psize, st->fifo_len);
    } else {
        ok = bus_read(paddr, st->fifo + st->fifo_len, psize);
        st->fifo_len += psize;
        ok = ok && drain_to_memory(st, false);
    }
    st->p_off += (st->cr & CR_PINC) ? ((st->cr & CR_PINCOS) ? 4 : psize) : 0;
    return ok;
}

/* Stream @n moves an item for @source (-1: memory-to-memory): NDTR, the flags, the end of the transfer */
static void transfer_item(RigStm32DmaState *s, unsigned n, int source)
{
    RigDmaStream *st = &s->stream[n];
    if (!move_item(st)) {
        set_flags(s, n, TEIF); /* 10.3.16: a bus error disables the stream */
        st->cr &= ~CR_EN;
        st->fifo_len = 0;
        return;
    }
    st->ndtr--;
    uint32_t done = st->reload - st->ndtr;
    if (2 * done >= st->reload && 2 * (done - 1) < st->reload) {
        set_flags(s, n, HTIF);
    }
    if (st->ndtr == 1 && source >= 0) {
        qemu_irq_pulse(s->eot1[source]);
    }
    if (st->ndtr > 0) {
        return;
    }
    if (direction(st) != DIR_M2P && !drain_to_memory(st, true)) {
        set_flags(s, n, TEIF);
    }
    set_flags(s, n, TCIF);
    if ((st->cr & (CR_CIRC | CR_DBM)) && direction(st) != DIR_M2M) {
        st->ndtr = st->reload; /* 10.3.9, 10.3.10: the next round */
        st->p_off = st->m_off = 0;
        st->cr ^= (st->cr & CR_DBM) ? CR_CT : 0;
    } else {
        st->cr &= ~CR_EN;
    }
}

/* The stream that request @source reaches: enabled, its CHSEL the request's channel, not memory-to-memory */
static int stream_of(RigStm32DmaState *s, unsigned source)
{
    for (unsigned i = 0; i < ARRAY_SIZE(request_map); i++) {
        unsigned n = request_map[i].stream;
        const RigDmaStream *st = &s->stream[n];
        if (request_map[i].dma == s->controller && request_map[i].source == source && (st->cr & CR_EN) &&
            (st->cr >> CR_CHSEL_SHIFT & 7) == request_map[i].channel && direction(st) != DIR_M2M && st->ndtr > 0) {
            return n;
        }
    }
    return -1;
}

/* The lazy peripherals up to now before a register access, and again after a write (rig_stm32_dma_add_sync):
 * a stream enabled or reconfigured changes the instants they need a QEMU timer for */
static void sync_peripherals(RigStm32DmaState *s)
{
    for (unsigned i = 0; i < s->n_sync; i++) {
        s->sync[i].fn(s->sync[i].opaque);
    }
}

/* Serves the pending requests, those raised while serving included. A firmware whose transfers raise
 * their own requests again (a timer's UG written by its update DMA) would never let virtual time move:
 * after RIG_DMA_ROUNDS_AT_ONCE rounds of them the rest wait a while, and the core runs on */
static void serve(RigStm32DmaState *s)
{
    unsigned rounds = 0;
    bool any = true;
    if (s->busy) {
        return;
    }
    s->busy = true;
    while (any && rounds++ < RIG_DMA_ROUNDS_AT_ONCE) {
        any = false;
        for (unsigned source = 0; source < RIG_DMA_SOURCES; source++) {
            if (s->pending[source]) {
                s->pending[source] = false;
                any = true;
                int n = stream_of(s, source);
                if (n >= 0) {
                    transfer_item(s, n, source);
                }
            }
        }
    }
    s->busy = false;
    update_irqs(s);
    if (any) { /* (armed last: with the core asleep, arming moves virtual time on to it at once) */
        timer_mod(s->later, qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL) + RIG_DMA_PACE_NS);
    }
}

/* (the lazy peripherals after: their requests' streams moved on outside their catch-ups) */
static void serve_later(void *opaque)
{
    serve(opaque);
    sync_peripherals(opaque);
}

void rig_stm32_dma_add_sync(RigStm32DmaState *s, void (*fn)(void *opaque), void *opaque)
{
    assert(s->n_sync < RIG_DMA_SYNCS);
    s->sync[s->n_sync].fn = fn;
    s->sync[s->n_sync++].opaque = opaque;
}

const RigDmaStream *rig_stm32_dma_request_target(RigStm32DmaState *s, unsigned source)
{
    int n = dma_clocked(s) ? stream_of(s, source) : -1;
    return n < 0 ? NULL : &s->stream[n];
}

bool rig_stm32_dma_request_stream(RigStm32DmaState *s, unsigned source, uint32_t *cr, uint32_t *ndtr, uint32_t *reload)
{
    const RigDmaStream *st = rig_stm32_dma_request_target(s, source);
    if (st == NULL) {
        return false;
    }
    *cr = st->cr;
    *ndtr = st->ndtr;
    *reload = st->reload;
    return true;
}

static void request_changed(void *opaque, int source, int level)
{
    RigStm32DmaState *s = opaque;
    s->level[source] = level;
    if (level && dma_clocked(s)) { /* (raised again while up: a timer's DMAR burst asking for its next item) */
        s->pending[source] = true;
        serve(s);
    }
}

/* EN set: the configuration as the stream runs it (10.5.5: MSIZE follows PSIZE and PINCOS is cleared in
 * direct mode; DMDIS is set for memory-to-memory, which runs at once); a request already up is served */
static void stream_enabled(RigStm32DmaState *s, unsigned n)
{
    RigDmaStream *st = &s->stream[n];
    st->reload = st->ndtr;
    st->p_off = st->m_off = st->fifo_len = 0;
    if (direction(st) == DIR_M2M) {
        st->fcr |= FCR_DMDIS;
    } else if (!(st->fcr & FCR_DMDIS)) {
        st->cr = (st->cr & ~(3u << CR_MSIZE_SHIFT | CR_PINCOS)) | (st->cr >> CR_PSIZE_SHIFT & 3) << CR_MSIZE_SHIFT;
    }
    if (direction(st) == DIR_M2M && s->controller == 1) {
        /* 10.3.6: DMA1's peripheral port is not on the bus matrix, so it reads no memory: a bus error */
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-dma: DMA1 stream %u: memory-to-memory is DMA2's only\n", n);
        set_flags(s, n, TEIF);
        st->cr &= ~CR_EN;
        return;
    }
    if (direction(st) == DIR_M2M) {
        bool was_busy = s->busy;
        s->busy = true; /* (requests its accesses raise wait until it is done) */
        while ((st->cr & CR_EN) && st->ndtr > 0) {
            transfer_item(s, n, -1);
        }
        s->busy = was_busy;
    }
    for (unsigned i = 0; i < ARRAY_SIZE(request_map); i++) {
        if (request_map[i].dma == s->controller && request_map[i].stream == n && s->level[request_map[i].source]) {
            s->pending[request_map[i].source] = true;
        }
    }
    serve(s);
}

static void write_stream(RigStm32DmaState *s, unsigned n, int r, uint32_t v)
{
    RigDmaStream *st = &s->stream[n];
    uint32_t *regs[S_REGS] = { &st->cr, &st->ndtr, &st->par, &st->m0ar, &st->m1ar, &st->fcr };
    uint32_t writable = stream_registers[r].reg.writable;
    bool enabled = st->cr & CR_EN;
    if (enabled) {
        bool other_buffer =
            (st->cr & CR_DBM) && ((r == S_M0AR && (st->cr & CR_CT)) || (r == S_M1AR && !(st->cr & CR_CT)));
        uint32_t now = other_buffer ? writable : stream_registers[r].writable_enabled;
        if ((v ^ *regs[r]) & writable & ~now) {
            qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-dma: stream %u %s written while enabled: bits ignored\n", n,
                          stream_registers[r].reg.name);
        }
        writable = now;
    }
    *regs[r] = (*regs[r] & ~writable) | (v & writable);
    if (r == S_CR && enabled && !(v & CR_EN) && st->ndtr > 0) {
        set_flags(s, n, TCIF); /* 10.3.17: a stream disabled under way ends its transfer with TCIF */
    } else if (r == S_CR && !enabled && (v & CR_EN)) {
        stream_enabled(s, n);
    }
}

static uint64_t dma_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32DmaState *s = opaque;
    if (!dma_clocked(s)) {
        return 0;
    }
    sync_peripherals(s);
    if (offset >= STREAM_BASE && offset < STREAM_BASE + RIG_DMA_STREAMS * STREAM_STRIDE) {
        const RigDmaStream *st = &s->stream[(offset - STREAM_BASE) / STREAM_STRIDE];
        const uint32_t values[S_REGS] = { st->cr, st->ndtr, st->par, st->m0ar, st->m1ar, st->fcr };
        return values[(offset - STREAM_BASE) % STREAM_STRIDE / 4];
    }
    switch (rig_register_index(dma_registers, ARRAY_SIZE(dma_registers), offset)) {
    case R_LISR:
    case R_HISR:
        return s->isr[offset / 4];
    case R_LIFCR:
    case R_HIFCR:
        return 0;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-dma: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
}

static void dma_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32DmaState *s = opaque;
    uint32_t v = (uint32_t)value;
    if (!dma_clocked(s)) {
        return;
    }
    sync_peripherals(s);
    if (offset >= STREAM_BASE && offset < STREAM_BASE + RIG_DMA_STREAMS * STREAM_STRIDE) {
        write_stream(s, (offset - STREAM_BASE) / STREAM_STRIDE, (offset - STREAM_BASE) % STREAM_STRIDE / 4, v);
        update_irqs(s);
        sync_peripherals(s); /* (again: a lazy peripheral sets its timer by the stream as it is now) */
        return;
    }
    switch (rig_register_index(dma_registers, ARRAY_SIZE(dma_registers), offset)) {
    case R_LIFCR:
    case R_HIFCR:
        s->isr[offset / 4 - 2] &= ~(v & dma_registers[R_LIFCR].writable);
        update_irqs(s);
        break;
    case R_LISR:
    case R_HISR:
        break;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-dma: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
    }
}

static const MemoryRegionOps dma_ops = {
    .read = dma_read,
    .write = dma_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void dma_reset(DeviceState *dev)
{
    RigStm32DmaState *s = RIG_STM32_DMA(dev);
    s->isr[0] = dma_registers[R_LISR].reset;
    s->isr[1] = dma_registers[R_HISR].reset;
    for (unsigned n = 0; n < RIG_DMA_STREAMS; n++) {
        RigDmaStream *st = &s->stream[n];
        memset(st, 0, sizeof(*st));
        st->cr = stream_registers[S_CR].reg.reset;
        st->ndtr = stream_registers[S_NDTR].reg.reset;
        st->par = stream_registers[S_PAR].reg.reset;
        st->m0ar = stream_registers[S_M0AR].reg.reset;
        st->m1ar = stream_registers[S_M1AR].reg.reset;
        st->fcr = stream_registers[S_FCR].reg.reset;
    }
    memset(s->pending, 0, sizeof(s->pending));
    timer_del(s->later);
    update_irqs(s);
}

static void dma_realize(DeviceState *dev, Error **errp)
{
    RigStm32DmaState *s = RIG_STM32_DMA(dev);
    if (s->controller < 1 || s->controller > 2) {
        error_setg(errp, "rig-stm32f4-dma: controller is 1 or 2 (DMA1, DMA2), not %u", s->controller);
    }
}

static void dma_init(Object *obj)
{
    RigStm32DmaState *s = RIG_STM32_DMA(obj);
    memory_region_init_io(&s->iomem, obj, &dma_ops, s, TYPE_RIG_STM32_DMA, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    for (unsigned n = 0; n < RIG_DMA_STREAMS; n++) {
        sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq[n]);
    }
    qdev_init_gpio_in_named(DEVICE(obj), request_changed, "request", RIG_DMA_SOURCES);
    qdev_init_gpio_out_named(DEVICE(obj), s->eot1, "eot1", RIG_DMA_SOURCES);
    s->later = timer_new_ns(QEMU_CLOCK_VIRTUAL, serve_later, s);
}

static Property dma_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32DmaState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_UINT8("controller", RigStm32DmaState, controller, 0),
    DEFINE_PROP_END_OF_LIST(),
};

static void dma_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = dma_reset;
    dc->realize = dma_realize;
    device_class_set_props(dc, dma_properties);
}

static const TypeInfo dma_info = {
    .name = TYPE_RIG_STM32_DMA,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32DmaState),
    .instance_init = dma_init,
    .class_init = dma_class_init,
};

static void dma_register_types(void) { type_register_static(&dma_info); }

type_init(dma_register_types)
