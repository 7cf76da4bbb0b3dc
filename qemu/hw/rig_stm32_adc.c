/*
 * The STM32F4's ADCs, RM0090 section 13 (the F405's ADC1, ADC2 and ADC3 at 0x40012000, 0x40012100 and
 * 0x40012200, their common registers at 0x40012300) and RM0383 section 11 (the F411's ADC1 alone): one
 * device for the block, property "count" (the ADCs the chip has) and "chip" (405 or 411: the internal
 * channels), "dma" (DMA2, for its lazy scans) and "eager" (below). The registers are tables of data
 * (13.13.18, the ADC register map; rig_stm32_adc_regs.h): SR, CR1, CR2, SMPR1/2, JOFR1-4, HTR, LTR,
 * SQR1-3, JSQR, JDR1-4, DR per ADC, and CSR, CCR, CDR in common.
 *
 * A conversion takes its channel's sampling time (SMPx: 3 ... 480 cycles) and the resolution's bits (RES:
 * 12, 10, 8 or 6 cycles; 13.5) of the ADC clock, PCLK2 / 2, 4, 6 or 8 (CCR.ADCPRE), taken as the conversion
 * starts. Regular conversions start on SWSTART with ADON: one channel (SQ1), or with SCAN the sequence
 * SQ1 ... SQ(L+1); with CONT again and again. Injected ones on JSWSTART (JL+1 conversions from JSQ(4-JL),
 * into JDR1 ..., less JOFRx, sign-extended), which reset a regular conversion under way and resume it
 * after (13.3.9), or after each regular sequence with JAUTO. EOC comes at the end of each regular
 * conversion (EOCS = 1) or of the sequence (EOCS = 0); DR right or left aligned (ALIGN, 13.7); with DMA, a
 * DMA request after each regular conversion, which the DMA's read of DR takes (ADC1 to DMA2 stream 0 or
 * 4 channel 0, ADC2 stream 2 or 3 channel 1, ADC3 stream 0 or 1 channel 2: RM0090 table 43, in the DMA's
 * request map); overrun (13.8.1, with DMA = 1 or EOCS = 1): a regular conversion ending while DR holds
 * data not read sets OVR and stops the regular conversions, and triggers are ignored until OVR is cleared.
 * The analog watchdog (AWDEN, JAWDEN, AWDSGL, AWDCH against HTR and LTR on the 12-bit value) sets AWD. The
 * interrupt (EOCIE, JEOCIE, AWDIE, OVRIE) of the three ADCs is one NVIC line, 18. CSR shows the three SRs.
 *
 * Inputs: each external channel (0-15) at the volts the rig sets (rig_stm32_adc_set_input: 0 V until
 * then), against VDDA = VREF+ = 3.3 V; a pin above VDDA reads full scale. The internal channels of ADC1
 * (13.10, 13.11; DS8626, DS10314): the temperature sensor at 25 degC, 0.76 V (channel 16 on the F405,
 * 18 on the F411), VREFINT 1.21 V (17), both with CCR.TSVREFE; VBAT with CCR.VBATE on channel 18, a fixed
 * 3.0 V battery through the chip's bridge: VBAT/2 on the F405, VBAT/4 on the F411 (VBAT wins over the
 * F411's sensor on the channel they share).
 *
 * Lazy: what finished by now is worked out when the firmware touches the ADC (or an input changes), at
 * the instants it finished; a QEMU timer ends a conversion only while an interrupt must come at that
 * instant (each QEMU timer under icount wakes QEMU's main loop). A long run of continuous conversions
 * nobody reads is skipped by whole sequences. A scan feeding a DMA stream (CR2.DMA; DMA2's stream reading
 * DR into memory) is lazy too, its transfers made at each conversion's instant in the catch-up, which also
 * comes before each access to DMA2's registers (rig_stm32_dma_add_sync) and at each stop of the rig's link
 * (rig_link_sync_add), so NDTR and the stream's flags read are the chip's; a QEMU timer then only for the
 * instant of the stream's HTIF or TCIF with HTIE or TCIE (worked out ahead: the regular sequence repeats),
 * and for each conversion until the memory the stream writes is settled: the core reads that memory with
 * no catch-up, but once every item of the buffer (both, in double-buffer mode) was written after the last
 * change (an ADC register or input, the stream's configuration), each later round writes the values
 * already there, the buffer a whole number of sequences long. So the memory holds at every instant what
 * the chip's would, unless something else writes it (the core: then the stream overwrites it at the next
 * catch-up, not at the conversion's instant). Eager (a QEMU timer for every DMA conversion): a stream's
 * transfer-error interrupt (TEIE: a bus error's instant is not known ahead), one not reading DR, a buffer
 * that is no whole number of sequences, injected conversions under way or JAUTO, or the property "eager".
 *
 * Not modelled: external triggers (EXTEN, EXTSEL, JEXTEN, JEXTSEL stored), discontinuous mode (DISCEN,
 * JDISCEN, DISCNUM stored), the multi-ADC modes (CCR.MULTI, DELAY, DMA, DDS stored; CDR reads 0), the
 * ADC's power-up time (tSTAB), DDS = 0's stop after the DMA's last transfer (requests go on as with DDS =
 * 1), the DMA bit's re-arming after an overrun (requests resume once OVR is cleared).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32_adc_regs.h"
#include "rig_stm32f4.h"

#define APB2ENR 0x44
#define APB2ENR_ADC1EN 8 /* ADC2EN 9, ADC3EN 10 */
#define UNIT_STRIDE 0x100
#define COMMON_BASE 0x300

typedef enum { CONV_NONE, CONV_REGULAR, CONV_INJECTED } ConvKind;

typedef struct RigAdcUnit {
    uint32_t regs[R_REGS];
    uint32_t input_uv[ADC_INPUTS];
    QEMUTimer *timer;
    bool regular;  /* a regular sequence under way (its next conversion: reg_rank) */
    bool injected; /* an injected sequence under way (inj_rank) */
    unsigned reg_rank, inj_rank;
    ConvKind conv; /* the conversion under way */
    int64_t conv_start_ns, conv_end_ns;
    bool dr_full; /* DR holds a regular result not yet read (overrun detection) */
    bool dma_level;
    /* the stream the lazy scan feeds as last seen (a change: its memory unsettled again), and the
     * conversions still to be made at their own instants before that memory is settled */
    struct {
        const RigDmaStream *stream;
        uint32_t cr, par, m0ar, m1ar, reload;
    } seen;
    bool seen_valid;
    uint32_t unsettled;
} RigAdcUnit;

struct RigStm32AdcState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    RigStm32DmaState *dma_ctl; /* property "dma": DMA2, which the requests reach */
    bool eager;                /* property "eager": a QEMU timer for every DMA conversion, needed or not */
    uint8_t count;             /* property "count": the ADCs the chip has (3 on the F405, 1 on the F411) */
    uint32_t chip;             /* property "chip": 405 or 411 */
    uint32_t ccr;
    qemu_irq irq; /* the ADCs' global interrupt */
    qemu_irq dma[ADC_UNITS];
    bool catching_up; /* (the DMA's read of DR during a conversion's end is no new catch-up) */
    RigAdcUnit unit[ADC_UNITS];
};

static bool unit_clocked(RigStm32AdcState *s, unsigned n)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, APB2ENR, APB2ENR_ADC1EN + n);
}

static unsigned bits(const RigAdcUnit *u) { return resolution_bits[u->regs[R_CR1] >> CR1_RES_SHIFT & 3]; }

static unsigned sampling(const RigAdcUnit *u, unsigned channel)
{
    if (channel >= ADC_CHANNELS) {
        return sampling_cycles[0];
    }
    uint32_t smpr = channel < 10 ? u->regs[R_SMPR2] : u->regs[R_SMPR1];
    return sampling_cycles[smpr >> (3 * (channel % 10)) & 7];
}

/* The ADC clock: PCLK2 / 2, 4, 6, 8 (CCR.ADCPRE, 13.13.17) */
static uint64_t adc_hz(RigStm32AdcState *s)
{
    uint64_t pclk2 = s->rcc != NULL ? rig_stm32_rcc_pclk_hz(s->rcc, 2) : 16000000;
    return MAX(pclk2 / (2 * ((s->ccr >> CCR_ADCPRE_SHIFT & 3) + 1)), 1u);
}

/* 13.5: Tconv = sampling time + the resolution's bits, in ADC clock cycles; in ns, rounded up */
static int64_t conversion_ns(RigStm32AdcState *s, const RigAdcUnit *u, unsigned channel)
{
    uint64_t cycles = sampling(u, channel) + bits(u), hz = adc_hz(s);
    return (int64_t)((cycles * NANOSECONDS_PER_SECOND + hz - 1) / hz);
}

/* The regular sequence's length (SQR1.L + 1; one without SCAN) and its channel at @rank */
static unsigned regular_length(const RigAdcUnit *u)
{
    return (u->regs[R_CR1] & CR1_SCAN) ? (u->regs[R_SQR1] >> 20 & 0xF) + 1 : 1;
}

static unsigned regular_channel(const RigAdcUnit *u, unsigned rank)
{
    uint32_t sqr = rank < 6 ? u->regs[R_SQR3] : rank < 12 ? u->regs[R_SQR2] : u->regs[R_SQR1];
    return sqr >> (5 * (rank % 6)) & 0x1F;
}

/* 13.13.12: JL + 1 conversions of JSQ(4 - JL) ... JSQ4 (one without SCAN) */
static unsigned injected_length(const RigAdcUnit *u)
{
    return (u->regs[R_CR1] & CR1_SCAN) ? (u->regs[R_JSQR] >> 20 & 3) + 1 : 1;
}

static unsigned injected_channel(const RigAdcUnit *u, unsigned rank)
{
    unsigned first = 3 - (u->regs[R_JSQR] >> 20 & 3);
    return u->regs[R_JSQR] >> (5 * (first + rank)) & 0x1F;
}

/* The volts on @channel of ADC @n in microvolts */
static uint32_t channel_uv(RigStm32AdcState *s, unsigned n, unsigned channel)
{
    if (channel < ADC_INPUTS) {
        return s->unit[n].input_uv[channel];
    }
    if (n != 0 || channel >= ADC_CHANNELS) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-adc: ADC%u has no channel %u (reads 0)\n", n + 1, channel);
        return 0;
    }
    bool sensor_on = s->ccr & CCR_TSVREFE, vbat_on = s->ccr & CCR_VBATE;
    unsigned temp_channel = s->chip == 411 ? 18 : 16;
    if (channel == 18 && vbat_on) {
        return s->chip == 411 ? VBAT_UV / 4 : VBAT_UV / 2;
    }
    if (channel == temp_channel && sensor_on) {
        return TEMP_25C_UV;
    }
    return channel == 17 && sensor_on ? VREFINT_UV : 0;
}

/* The code of @uv at @resolution bits: round(V / VDDA x (2^bits - 1)), full scale above VDDA */
static uint32_t code_of(uint32_t uv, unsigned resolution)
{
    uint64_t full = (1u << resolution) - 1;
    return (uint32_t)((MIN(uv, VDDA_UV) * full + VDDA_UV / 2) / VDDA_UV);
}

/* 13.7 (figures 37, 38): the 16-bit data register's value; an injected value is signed (less JOFRx) */
static uint32_t aligned(const RigAdcUnit *u, int32_t value, bool injected)
{
    unsigned b = bits(u);
    if (u->regs[R_CR2] & CR2_ALIGN) {
        if (injected) { /* SEXT in bit 15, the data below it (6 bits: from bit 1) */
            return (uint32_t)(value * (1 << (b == 6 ? 1 : 15 - b))) & 0xFFFF;
        }
        return (uint32_t)value << (b == 6 ? 2 : 16 - b); /* (6 bits: on a byte) */
    }
    return (uint32_t)value & 0xFFFF; /* (an injected value sign-extended) */
}

static void update_irq(RigStm32AdcState *s)
{
    bool level = false;
    for (unsigned n = 0; n < s->count; n++) {
        uint32_t sr = s->unit[n].regs[R_SR], cr1 = s->unit[n].regs[R_CR1];
        level |= ((sr & SR_EOC) && (cr1 & CR1_EOCIE)) || ((sr & SR_JEOC) && (cr1 & CR1_JEOCIE)) ||
                 ((sr & SR_AWD) && (cr1 & CR1_AWDIE)) || ((sr & SR_OVR) && (cr1 & CR1_OVRIE));
    }
    qemu_set_irq(s->irq, level);
}

static void set_dma(RigStm32AdcState *s, unsigned n, bool level)
{
    if (s->unit[n].dma_level != level) {
        s->unit[n].dma_level = level;
        qemu_set_irq(s->dma[n], level);
    }
}

/* The conversion to do next, if any, from @at_ns: injected ones first (13.3.9) */
static void start_next(RigStm32AdcState *s, RigAdcUnit *u, int64_t at_ns)
{
    unsigned channel;
    if (u->injected) {
        u->conv = CONV_INJECTED;
        channel = injected_channel(u, u->inj_rank);
        u->regs[R_SR] |= SR_JSTRT;
    } else if (u->regular) {
        u->conv = CONV_REGULAR;
        channel = regular_channel(u, u->reg_rank);
        u->regs[R_SR] |= SR_STRT;
    } else {
        u->conv = CONV_NONE;
        return;
    }
    u->conv_start_ns = at_ns;
    u->conv_end_ns = at_ns + conversion_ns(s, u, channel);
}

/* 13.3.7: the analog watchdog on the 12-bit value */
static void watchdog(RigAdcUnit *u, unsigned channel, uint32_t code12, bool injected)
{
    uint32_t cr1 = u->regs[R_CR1];
    bool on = injected ? (cr1 & CR1_JAWDEN) : (cr1 & CR1_AWDEN);
    if (on && (!(cr1 & CR1_AWDSGL) || channel == (cr1 & CR1_AWDCH)) &&
        (code12 > u->regs[R_HTR] || code12 < u->regs[R_LTR])) {
        u->regs[R_SR] |= SR_AWD;
    }
}

/* The conversion under way ends (at conv_end_ns) */
static void finish(RigStm32AdcState *s, unsigned n)
{
    RigAdcUnit *u = &s->unit[n];
    int64_t at = u->conv_end_ns;
    bool injected = u->conv == CONV_INJECTED;
    unsigned channel = injected ? injected_channel(u, u->inj_rank) : regular_channel(u, u->reg_rank);
    uint32_t uv = channel_uv(s, n, channel);
    uint32_t code = code_of(uv, bits(u));
    watchdog(u, channel, code_of(uv, 12), injected);
    if (injected) {
        int32_t value = (int32_t)code - (int32_t)u->regs[R_JOFR1 + u->inj_rank];
        u->regs[R_JDR1 + u->inj_rank] = aligned(u, value, true);
        if (++u->inj_rank >= injected_length(u)) {
            u->injected = false;
            u->regs[R_SR] |= SR_JEOC;
        }
        start_next(s, u, at);
        return;
    }
    bool detect = u->regs[R_CR2] & (CR2_DMA | CR2_EOCS);
    if (detect && u->dr_full) { /* 13.8.1: data lost; the regular conversions stop */
        u->regs[R_SR] |= SR_OVR;
        u->regular = false;
        set_dma(s, n, false);
        start_next(s, u, at);
        return;
    }
    u->regs[R_DR] = aligned(u, (int32_t)code, false);
    u->dr_full = true;
    bool last = ++u->reg_rank >= regular_length(u);
    if (last || (u->regs[R_CR2] & CR2_EOCS)) {
        u->regs[R_SR] |= SR_EOC;
    }
    if (last) {
        u->reg_rank = 0;
        u->regular = (u->regs[R_CR2] & CR2_CONT) != 0;
        if ((u->regs[R_CR1] & CR1_JAUTO) && !u->injected) { /* 13.3.8: the injected group after */
            u->injected = true;
            u->inj_rank = 0;
        }
    }
    if (u->regs[R_CR2] & CR2_DMA) {
        u->unsettled -= u->unsettled > 0;
        set_dma(s, n, true);
    }
    start_next(s, u, at);
}

/* A run of continuous conversions nobody reads or watches changes nothing but time: whole sequences of it
 * are skipped, leaving one to carry out */
static void skip_sequences(RigStm32AdcState *s, RigAdcUnit *u, int64_t now)
{
    if (u->conv != CONV_REGULAR || u->reg_rank != 0 || u->injected || !(u->regs[R_CR2] & CR2_CONT) ||
        (u->regs[R_CR2] & (CR2_DMA | CR2_EOCS)) || (u->regs[R_CR1] & CR1_JAUTO)) {
        return;
    }
    int64_t sequence_ns = 0;
    for (unsigned r = 0; r < regular_length(u); r++) {
        sequence_ns += conversion_ns(s, u, regular_channel(u, r));
    }
    int64_t skip = (now - u->conv_start_ns) / sequence_ns - 1;
    if (skip > 0) {
        u->conv_start_ns += skip * sequence_ns;
        u->conv_end_ns += skip * sequence_ns;
    }
}

/* What ADC @n finished by now */
static void catch_up_unit(RigStm32AdcState *s, unsigned n)
{
    RigAdcUnit *u = &s->unit[n];
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    bool was = s->catching_up;
    s->catching_up = true;
    skip_sequences(s, u, now);
    while (u->conv != CONV_NONE && u->conv_end_ns <= now) {
        finish(s, n);
    }
    s->catching_up = was;
    update_irq(s);
}

#define DMA_CR_TEIE (1u << 2) /* RM0090 10.5.5, SxCR */
#define DMA_CR_HTIE (1u << 3)
#define DMA_CR_TCIE (1u << 4)
#define DMA_CR_DIR_MASK (3u << 6) /* 00: peripheral to memory */
#define DMA_CR_PINC (1u << 9)
#define DMA_CR_MINC (1u << 10)
#define DMA_CR_DBM (1u << 18)
#define DMA_CR_CT (1u << 19)

/* The end of the @k-th regular conversion from the one under way (its own end: k = 1), with no injected
 * one between; INT64_MAX past the sequence's end without CONT */
static int64_t regular_end(RigStm32AdcState *s, const RigAdcUnit *u, uint64_t k)
{
    unsigned length = regular_length(u), rank = u->reg_rank;
    int64_t at = u->conv_end_ns;
    bool cont = u->regs[R_CR2] & CR2_CONT;
    if (--k >= length && cont) { /* (any run of @length conversions takes one sequence's time) */
        int64_t sequence_ns = 0;
        for (unsigned r = 0; r < length; r++) {
            sequence_ns += conversion_ns(s, u, regular_channel(u, r));
        }
        at += (int64_t)(k / length) * sequence_ns;
        k %= length;
    }
    for (; k > 0; k--) {
        if (++rank >= length) {
            if (!cont) {
                return INT64_MAX;
            }
            rank = 0;
        }
        at += conversion_ns(s, u, regular_channel(u, rank));
    }
    return at;
}

/* The stream reads DR into memory, one item a regular conversion, each memory address always getting the
 * same rank's value (a buffer of whole sequences, or a single conversion), and raises no interrupt whose
 * instant is not known ahead: its transfers can wait for a catch-up */
static bool stream_lazy(RigStm32AdcState *s, unsigned n, const RigDmaStream *st)
{
    const RigAdcUnit *u = &s->unit[n];
    hwaddr dr = SYS_BUS_DEVICE(s)->mmio[0].addr + n * UNIT_STRIDE + adc_registers[R_DR].offset;
    unsigned length = regular_length(u);
    return !s->eager && u->conv == CONV_REGULAR && !u->injected && !(u->regs[R_CR1] & CR1_JAUTO) &&
           !(st->cr & (DMA_CR_DIR_MASK | DMA_CR_PINC | DMA_CR_TEIE)) && st->par == dr && st->reload % length == 0 &&
           ((st->cr & DMA_CR_MINC) || length == 1);
}

/* The memory the stream writes is unsettled again when it is not the one last seen (the stream's
 * configuration less CT, which each double-buffer round toggles) */
static void see_stream(RigAdcUnit *u, const RigDmaStream *st)
{
    uint32_t cr = st->cr & ~DMA_CR_CT;
    if (!u->seen_valid || u->seen.stream != st || u->seen.cr != cr || u->seen.par != st->par ||
        u->seen.m0ar != st->m0ar || u->seen.m1ar != st->m1ar || u->seen.reload != st->reload) {
        u->seen.stream = st;
        u->seen.cr = cr;
        u->seen.par = st->par;
        u->seen.m0ar = st->m0ar;
        u->seen.m1ar = st->m1ar;
        u->seen.reload = st->reload;
        u->seen_valid = true;
        u->unsettled = st->reload * ((st->cr & DMA_CR_DBM) ? 2 : 1);
    }
}

/* The instant ADC @n needs a QEMU timer for (INT64_MAX: none): the conversion under way's end while an
 * interrupt may follow it, or while its DMA request must be served then; a lazy scan's stream's HTIF or
 * TCIF with their interrupts enabled. With CR2.DMA and no stream to take the request, nothing needs its
 * instant: it stays up (an overrun at the next conversion), and a stream enabled later brings the ADC up
 * to now first */
static int64_t deadline(RigStm32AdcState *s, unsigned n)
{
    RigAdcUnit *u = &s->unit[n];
    if (u->conv == CONV_NONE) {
        return INT64_MAX;
    }
    if (u->regs[R_CR1] & (CR1_EOCIE | CR1_JEOCIE | CR1_AWDIE | CR1_OVRIE) || (s->eager && (u->regs[R_CR2] & CR2_DMA))) {
        return u->conv_end_ns;
    }
    const RigDmaStream *st = NULL;
    if ((u->regs[R_CR2] & CR2_DMA) && s->dma_ctl != NULL) {
        st = rig_stm32_dma_request_target(s->dma_ctl, RIG_DMA_ADC(n + 1));
    }
    if (st == NULL) {
        u->seen_valid = false;
        return INT64_MAX;
    }
    if (!stream_lazy(s, n, st)) {
        u->seen_valid = false;
        return u->conv_end_ns;
    }
    see_stream(u, st);
    if (u->unsettled > 0) {
        return u->conv_end_ns;
    }
    int64_t when = INT64_MAX;
    if (st->cr & DMA_CR_TCIE) {
        when = regular_end(s, u, st->ndtr);
    }
    if (st->cr & DMA_CR_HTIE) { /* (HTIF: the item with 2 x done >= reload first; rig_stm32_dma.c) */
        uint32_t done = st->reload - st->ndtr, half = (st->reload + 1) / 2;
        when = MIN(when, regular_end(s, u, done < half ? half - done : st->ndtr + half));
    }
    return when;
}

static void arm(RigStm32AdcState *s, unsigned n)
{
    RigAdcUnit *u = &s->unit[n];
    int64_t when = deadline(s, n);
    if (when == INT64_MAX) {
        timer_del(u->timer);
    } else if (!timer_pending(u->timer) || timer_expire_time_ns(u->timer) != when) {
        timer_mod(u->timer, when);
    }
}

static void catch_up_all(RigStm32AdcState *s)
{
    if (s->catching_up) {
        return;
    }
    for (unsigned n = 0; n < s->count; n++) {
        catch_up_unit(s, n);
        arm(s, n);
    }
}

/* The QEMU timer, an access to DMA2's registers, the link's stop: the ADCs up to now */
static void up_to_now(void *opaque) { catch_up_all(opaque); }

/* CR2's start bits (13.3.5, 13.3.9): SWSTART and JSWSTART read 1 until their conversion starts, at once */
static void write_cr2(RigStm32AdcState *s, unsigned n, uint32_t value)
{
    RigAdcUnit *u = &s->unit[n];
    uint32_t writable = adc_registers[R_CR2].writable;
    u->regs[R_CR2] = (u->regs[R_CR2] & ~writable) | (value & writable);
    uint32_t cr2 = u->regs[R_CR2];
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    u->regs[R_CR2] &= ~(CR2_SWSTART | CR2_JSWSTART);
    if (!(cr2 & CR2_ADON)) { /* off: what was under way stops */
        u->regular = u->injected = false;
        u->conv = CONV_NONE;
        return;
    }
    if ((cr2 & CR2_JSWSTART) && !u->injected) {
        u->injected = true;
        u->inj_rank = 0;
        if (u->conv == CONV_REGULAR) { /* reset, resumed after the injected group */
            u->conv = CONV_NONE;
        }
    }
    if ((cr2 & CR2_SWSTART) && !u->regular && !(u->regs[R_SR] & SR_OVR)) {
        u->regular = true;
        u->reg_rank = 0;
    }
    if (u->conv == CONV_NONE) {
        start_next(s, u, now);
    }
}

static uint64_t adc_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32AdcState *s = opaque;
    unsigned n = offset / UNIT_STRIDE;
    catch_up_all(s);
    if (offset >= COMMON_BASE) {
        int r = rig_register_index(common_registers, ARRAY_SIZE(common_registers), offset - COMMON_BASE);
        if (r < 0) {
            qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-adc: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
            return 0;
        }
        if (!unit_clocked(s, 0) && !unit_clocked(s, 1) && !unit_clocked(s, 2)) {
            return 0;
        }
        uint32_t csr = 0;
        for (unsigned k = 0; k < s->count; k++) {
            csr |= s->unit[k].regs[R_SR] << (8 * k);
        }
        return r == C_CSR ? csr : r == C_CCR ? s->ccr : 0;
    }
    int r = rig_register_index(adc_registers, ARRAY_SIZE(adc_registers), offset % UNIT_STRIDE);
    if (r < 0 || n >= s->count) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-adc: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    if (!unit_clocked(s, n)) {
        return 0;
    }
    RigAdcUnit *u = &s->unit[n];
    uint32_t value = u->regs[r];
    if (r == R_DR) { /* 13.13.1: reading DR clears EOC; the DMA's read takes its request */
        u->regs[R_SR] &= ~SR_EOC;
        u->dr_full = false;
        set_dma(s, n, false);
        update_irq(s);
    }
    return value;
}

static void adc_write(void *opaque, hwaddr offset, uint64_t v64, unsigned size)
{
    RigStm32AdcState *s = opaque;
    uint32_t value = v64;
    unsigned n = offset / UNIT_STRIDE;
    catch_up_all(s);
    if (offset >= COMMON_BASE) {
        int r = rig_register_index(common_registers, ARRAY_SIZE(common_registers), offset - COMMON_BASE);
        if (r < 0 || r != C_CCR) {
            qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-adc: write to %s offset 0x%" HWADDR_PRIx "\n",
                          r < 0 ? "reserved" : "read-only", offset);
            return;
        }
        if (!unit_clocked(s, 0) && !unit_clocked(s, 1) && !unit_clocked(s, 2)) {
            return;
        }
        s->ccr = value & common_registers[C_CCR].writable;
        if (s->ccr & CCR_MULTI) {
            qemu_log_mask(LOG_UNIMP, "rig-stm32f4-adc: multi-ADC mode %u not modelled\n", s->ccr & CCR_MULTI);
        }
        for (unsigned k = 0; k < s->count; k++) { /* (the internal channels' volts, the clock) */
            s->unit[k].seen_valid = false;
            arm(s, k);
        }
        return;
    }
    int r = rig_register_index(adc_registers, ARRAY_SIZE(adc_registers), offset % UNIT_STRIDE);
    if (r < 0 || n >= s->count) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-adc: write to reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    if (!unit_clocked(s, n)) {
        return;
    }
    RigAdcUnit *u = &s->unit[n];
    if (r == R_SR) { /* rc_w0 */
        u->regs[R_SR] &= value | ~adc_registers[R_SR].writable;
    } else if (r == R_CR2) {
        write_cr2(s, n, value);
    } else if (adc_registers[r].writable == 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-adc: write to read-only %s\n", adc_registers[r].name);
    } else {
        u->regs[r] = (u->regs[r] & ~adc_registers[r].writable) | (value & adc_registers[r].writable);
    }
    u->seen_valid = false; /* (what a scan writes may differ from now on) */
    update_irq(s);
    arm(s, n);
}

bool rig_stm32_adc_set_input(DeviceState *dev, unsigned adc, unsigned channel, uint32_t microvolts)
{
    RigStm32AdcState *s = RIG_STM32_ADC(dev);
    if (adc < 1 || adc > s->count || channel >= ADC_INPUTS) {
        return false;
    }
    catch_up_all(s); /* (conversions that ended before now read the volts before) */
    RigAdcUnit *u = &s->unit[adc - 1];
    if (u->input_uv[channel] != microvolts) {
        u->input_uv[channel] = microvolts;
        u->seen_valid = false;
        arm(s, adc - 1);
    }
    return true;
}

static const MemoryRegionOps adc_ops = {
    .read = adc_read,
    .write = adc_write,
    .endianness = DEVICE_LITTLE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
    .valid.min_access_size = 1,
    .valid.max_access_size = 4,
};

static void adc_reset(DeviceState *dev)
{
    RigStm32AdcState *s = RIG_STM32_ADC(dev);
    s->ccr = common_registers[C_CCR].reset;
    for (unsigned n = 0; n < ADC_UNITS; n++) {
        RigAdcUnit *u = &s->unit[n];
        for (unsigned r = 0; r < R_REGS; r++) {
            u->regs[r] = adc_registers[r].reset;
        }
        u->regular = u->injected = false;
        u->conv = CONV_NONE;
        u->dr_full = false;
        u->seen_valid = false;
        u->unsettled = 0;
        if (u->timer != NULL) {
            timer_del(u->timer);
        }
        if (n < s->count) {
            set_dma(s, n, false);
        }
        /* (the inputs are the board's: a reset keeps them) */
    }
    qemu_set_irq(s->irq, 0);
}

static void adc_realize(DeviceState *dev, Error **errp)
{
    RigStm32AdcState *s = RIG_STM32_ADC(dev);
    if (s->count < 1 || s->count > ADC_UNITS || (s->chip != 405 && s->chip != 411)) {
        error_setg(errp, "rig-stm32f4-adc: count is 1..3 and chip 405 or 411, not %u and %u", s->count, s->chip);
        return;
    }
    for (unsigned n = 0; n < ADC_UNITS; n++) {
        s->unit[n].timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, up_to_now, s);
    }
    rig_link_sync_add(up_to_now, s);
    if (s->dma_ctl != NULL) {
        rig_stm32_dma_add_sync(s->dma_ctl, up_to_now, s);
    }
}

static void adc_init(Object *obj)
{
    RigStm32AdcState *s = RIG_STM32_ADC(obj);
    memory_region_init_io(&s->iomem, obj, &adc_ops, s, "rig-stm32f4-adc", 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq);
    qdev_init_gpio_out_named(DEVICE(obj), s->dma, "dma", ADC_UNITS);
}

static Property adc_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32AdcState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_LINK("dma", RigStm32AdcState, dma_ctl, TYPE_RIG_STM32_DMA, RigStm32DmaState *),
    DEFINE_PROP_BOOL("eager", RigStm32AdcState, eager, false),
    DEFINE_PROP_UINT8("count", RigStm32AdcState, count, 3),
    DEFINE_PROP_UINT32("chip", RigStm32AdcState, chip, 405),
    DEFINE_PROP_END_OF_LIST(),
};

static void adc_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = adc_reset;
    dc->realize = adc_realize;
    device_class_set_props(dc, adc_properties);
}

static const TypeInfo adc_info = {
    .name = TYPE_RIG_STM32_ADC,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32AdcState),
    .instance_init = adc_init,
    .class_init = adc_class_init,
};

static void adc_register_types(void) { type_register_static(&adc_info); }

type_init(adc_register_types)
