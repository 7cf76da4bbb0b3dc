/*
 * The STM32F4's ADCs, RM0090 section 13 (the F405's ADC1, ADC2 and ADC3 at 0x40012000, 0x40012100 and
 * 0x40012200, their common registers at 0x40012300) and RM0383 section 11 (the F411's ADC1 alone): one
 * device for the block, property "count" (the ADCs the chip has) and "chip" (405 or 411: the internal
 * channels). The registers are tables of data (13.13.18, the ADC register map): SR, CR1, CR2, SMPR1/2,
 * JOFR1-4, HTR, LTR, SQR1-3, JSQR, JDR1-4, DR per ADC, and CSR, CCR, CDR in common.
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
 * the instants it finished; a QEMU timer ends a conversion only while an interrupt or a DMA request must
 * come at that instant (each QEMU timer under icount wakes QEMU's main loop). A long run of continuous
 * conversions nobody reads is skipped by whole sequences.
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
#include "rig_stm32f4.h"

#define APB2ENR 0x44
#define APB2ENR_ADC1EN 8 /* ADC2EN 9, ADC3EN 10 */
#define UNIT_STRIDE 0x100
#define COMMON_BASE 0x300

/* RM0090 13.13.1-13.13.15 (table 71, the ADC register map): each ADC's registers */
static const RigRegister adc_registers[] = {
    { 0x00, "SR", 0x00000000, 0x0000003F },    /* AWD, EOC, JEOC, JSTRT, STRT, OVR: rc_w0 */
    { 0x04, "CR1", 0x00000000, 0x07C0FFFF },   /* AWDCH ... DISCNUM, JAWDEN, AWDEN, RES, OVRIE */
    { 0x08, "CR2", 0x00000000, 0x7F7F0F03 },   /* ADON, CONT, DMA, DDS, EOCS, ALIGN, J/EXTSEL, J/EXTEN, J/SWSTART */
    { 0x0C, "SMPR1", 0x00000000, 0x07FFFFFF }, /* SMP10 ... SMP18 */
    { 0x10, "SMPR2", 0x00000000, 0x3FFFFFFF }, /* SMP0 ... SMP9 */
    { 0x14, "JOFR1", 0x00000000, 0x00000FFF }, { 0x18, "JOFR2", 0x00000000, 0x00000FFF },
    { 0x1C, "JOFR3", 0x00000000, 0x00000FFF }, { 0x20, "JOFR4", 0x00000000, 0x00000FFF },
    { 0x24, "HTR", 0x00000FFF, 0x00000FFF },   { 0x28, "LTR", 0x00000000, 0x00000FFF },
    { 0x2C, "SQR1", 0x00000000, 0x00FFFFFF }, /* SQ13 ... SQ16, L */
    { 0x30, "SQR2", 0x00000000, 0x3FFFFFFF }, /* SQ7 ... SQ12 */
    { 0x34, "SQR3", 0x00000000, 0x3FFFFFFF }, /* SQ1 ... SQ6 */
    { 0x38, "JSQR", 0x00000000, 0x003FFFFF }, /* JSQ1 ... JSQ4, JL */
    { 0x3C, "JDR1", 0x00000000, 0x00000000 },  { 0x40, "JDR2", 0x00000000, 0x00000000 },
    { 0x44, "JDR3", 0x00000000, 0x00000000 },  { 0x48, "JDR4", 0x00000000, 0x00000000 },
    { 0x4C, "DR", 0x00000000, 0x00000000 },
};
enum {
    R_SR,
    R_CR1,
    R_CR2,
    R_SMPR1,
    R_SMPR2,
    R_JOFR1,
    R_HTR = R_JOFR1 + 4,
    R_LTR,
    R_SQR1,
    R_SQR2,
    R_SQR3,
    R_JSQR,
    R_JDR1,
    R_DR = R_JDR1 + 4,
    R_REGS
};

/* 13.13.16-13.13.18: the common registers, from 0x300 */
static const RigRegister common_registers[] = {
    { 0x00, "CSR", 0x00000000, 0x00000000 }, /* the three SRs, read only */
    { 0x04, "CCR", 0x00000000, 0x00C3EF1F }, /* MULTI, DELAY, DDS, DMA, ADCPRE, VBATE, TSVREFE */
    { 0x08, "CDR", 0x00000000, 0x00000000 }, /* multi mode's data: not modelled */
};
enum { C_CSR, C_CCR, C_CDR };

#define SR_AWD (1u << 0)
#define SR_EOC (1u << 1)
#define SR_JEOC (1u << 2)
#define SR_JSTRT (1u << 3)
#define SR_STRT (1u << 4)
#define SR_OVR (1u << 5)
#define CR1_AWDCH 0x1Fu
#define CR1_EOCIE (1u << 5)
#define CR1_AWDIE (1u << 6)
#define CR1_JEOCIE (1u << 7)
#define CR1_SCAN (1u << 8)
#define CR1_AWDSGL (1u << 9)
#define CR1_JAUTO (1u << 10)
#define CR1_JAWDEN (1u << 22)
#define CR1_AWDEN (1u << 23)
#define CR1_RES_SHIFT 24
#define CR1_OVRIE (1u << 26)
#define CR2_ADON (1u << 0)
#define CR2_CONT (1u << 1)
#define CR2_DMA (1u << 8)
#define CR2_EOCS (1u << 10)
#define CR2_ALIGN (1u << 11)
#define CR2_JSWSTART (1u << 22)
#define CR2_SWSTART (1u << 30)
#define CCR_MULTI 0x1Fu
#define CCR_ADCPRE_SHIFT 16
#define CCR_VBATE (1u << 22)
#define CCR_TSVREFE (1u << 23)

#define ADC_UNITS 3
#define ADC_INPUTS 16 /* the external channels */
#define ADC_CHANNELS 19
#define VDDA_UV 3300000u   /* the board's analog supply and reference */
#define TEMP_25C_UV 760000 /* DS8626 table 68 (temperature sensor): V25 */
#define VREFINT_UV 1210000 /* DS8626 table 69 (internal reference voltage): typical */
#define VBAT_UV 3000000    /* the backup battery: a fixed 3.0 V coin cell */

/* 13.13.4, 13.13.5: SMPx, the sampling time in ADC clock cycles; 13.13.2: RES, the bits (conversion cycles) */
static const uint16_t sampling_cycles[8] = { 3, 15, 28, 56, 84, 112, 144, 480 };
static const uint8_t resolution_bits[4] = { 12, 10, 8, 6 };

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
} RigAdcUnit;

struct RigStm32AdcState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    uint8_t count; /* property "count": the ADCs the chip has (3 on the F405, 1 on the F411) */
    uint32_t chip; /* property "chip": 405 or 411 */
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

/* A QEMU timer at the end of the conversion under way only when something must happen then */
static void arm(RigStm32AdcState *s, unsigned n)
{
    RigAdcUnit *u = &s->unit[n];
    bool needed = (u->regs[R_CR2] & CR2_DMA) || (u->regs[R_CR1] & (CR1_EOCIE | CR1_JEOCIE | CR1_AWDIE | CR1_OVRIE));
    if (u->conv != CONV_NONE && needed) {
        timer_mod(u->timer, u->conv_end_ns);
    } else {
        timer_del(u->timer);
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

static void timer_due(void *opaque) { catch_up_all(opaque); }

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
    s->unit[adc - 1].input_uv[channel] = microvolts;
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
        s->unit[n].timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, timer_due, s);
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
