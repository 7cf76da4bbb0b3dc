/*
 * The STM32F405 timers' register map and bits (RM0090 sections 17.4, 18.4, 19.4, 19.5, 20.4) as data,
 * for the timer model (rig_stm32_timer.c), its outputs (rig_stm32_timer_out.c) and its DMA bursts
 * (rig_stm32_timer_burst.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#ifndef RIG_STM32_TIMER_REGS_H
#define RIG_STM32_TIMER_REGS_H

#include "rig_stm32f4.h" /* (RIG_TIM_REGS) */

/* The kinds of timer */
enum { ADVANCED, GENERAL32, GENERAL16, TWO_CHANNEL, ONE_CHANNEL, BASIC, KINDS };
typedef struct RigTimerKind {
    uint8_t kind;
    uint8_t channels;
    bool wide;     /* 32-bit CNT, ARR and CCRx (TIM2, TIM5) */
    bool advanced; /* TIM1, TIM8: RCR, BDTR, four interrupt lines */
} RigTimerKind;
static const RigTimerKind kinds[KINDS] = {
    [ADVANCED] = { ADVANCED, 4, false, true },        [GENERAL32] = { GENERAL32, 4, true, false },
    [GENERAL16] = { GENERAL16, 4, false, false },     [TWO_CHANNEL] = { TWO_CHANNEL, 2, false, false },
    [ONE_CHANNEL] = { ONE_CHANNEL, 1, false, false }, [BASIC] = { BASIC, 0, false, false },
};

/*
 * The registers: offset, and the bits software can write on each kind of timer (0: that kind has no such
 * register), from the register descriptions of RM0090 rev 19: TIM1/TIM8 17.4, TIM2-TIM5 18.4 (TIM2 and
 * TIM5 32-bit), TIM9/TIM12 19.4, TIM10/TIM11/TIM13/TIM14 19.5, TIM6/TIM7 20.4. Every register resets
 * to 0. SR's bits are cleared by writing 0 (rc_w0); EGR reads 0.
 */
#define C16 0xFFFFu
#define C32 0xFFFFFFFFu
// clang-format off
enum { CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR, RCR, CCR1, CCR2, CCR3, CCR4, BDTR, DCR, DMAR,
       OR };
static const struct {
    uint16_t offset;
    uint32_t writable[KINDS]; /* ADVANCED, GENERAL32, GENERAL16, TWO_CHANNEL, ONE_CHANNEL, BASIC */
} registers[RIG_TIM_REGS] = {
    [CR1] =   { 0x00, { 0x3FF,  0x3FF,  0x3FF,  0x38F,  0x387, 0x8F } },
    [CR2] =   { 0x04, { 0x7FFD, 0xF8,   0xF8,   0x70,   0,     0x70 } },
    [SMCR] =  { 0x08, { 0xFFF7, 0xFFF7, 0xFFF7, 0xF7,   0,     0 } },
    [DIER] =  { 0x0C, { 0x7FFF, 0x5F5F, 0x5F5F, 0x47,   0x3,   0x101 } },
    [SR] =    { 0x10, { 0x1EFF, 0x1E5F, 0x1E5F, 0x647,  0x203, 0x1 } },
    [EGR] =   { 0x14, { 0xFF,   0x5F,   0x5F,   0x47,   0x3,   0x1 } },
    [CCMR1] = { 0x18, { 0xFFFF, 0xFFFF, 0xFFFF, 0x7F7F, 0x7F,  0 } },
    [CCMR2] = { 0x1C, { 0xFFFF, 0xFFFF, 0xFFFF, 0,      0,     0 } },
    [CCER] =  { 0x20, { 0x3FFF, 0xBBBB, 0xBBBB, 0xBB,   0xB,   0 } },
    [CNT] =   { 0x24, { C16,    C32,    C16,    C16,    C16,   C16 } },
    [PSC] =   { 0x28, { C16,    C16,    C16,    C16,    C16,   C16 } },
    [ARR] =   { 0x2C, { C16,    C32,    C16,    C16,    C16,   C16 } },
    [RCR] =   { 0x30, { 0xFF,   0,      0,      0,      0,     0 } },
    [CCR1] =  { 0x34, { C16,    C32,    C16,    C16,    C16,   0 } },
    [CCR2] =  { 0x38, { C16,    C32,    C16,    C16,    0,     0 } },
    [CCR3] =  { 0x3C, { C16,    C32,    C16,    0,      0,     0 } },
    [CCR4] =  { 0x40, { C16,    C32,    C16,    0,      0,     0 } },
    [BDTR] =  { 0x44, { 0xFFFF, 0,      0,      0,      0,     0 } },
    [DCR] =   { 0x48, { 0x1F1F, 0x1F1F, 0x1F1F, 0,      0,     0 } },
    [DMAR] =  { 0x4C, { C16,    C16,    C16,    0,      0,     0 } },
    [OR] =    { 0x50, { 0,      C32,    0,      0,      C32,   0 } }, /* or_writable below */
};
// clang-format on
/* The option registers' remap bits: TIM2's ITR1_RMP, TIM5's TI4_RMP, TIM11's TI1_RMP (18.4.19, 18.4.20,
 * 19.5.12); the other timers of a kind that has OR have none */
static const uint32_t or_writable[15] = { [2] = 0xC00, [5] = 0xC0, [11] = 0x3 };

/* TIMn's kind */
static const uint8_t kind_of[15] = {
    [1] = ADVANCED,     [2] = GENERAL32,    [3] = GENERAL16,    [4] = GENERAL16,   [5] = GENERAL32,
    [6] = BASIC,        [7] = BASIC,        [8] = ADVANCED,     [9] = TWO_CHANNEL, [10] = ONE_CHANNEL,
    [11] = ONE_CHANNEL, [12] = TWO_CHANNEL, [13] = ONE_CHANNEL, [14] = ONE_CHANNEL
};

/* The bits of register @reg software can write on timer @s */
static inline uint32_t writable(const RigStm32TimerState *s, int reg)
{
    return registers[reg].writable[s->kind->kind] & (reg == OR ? or_writable[s->index] : 0xFFFFFFFFu);
}

/* The register at @offset of timer @s, or -1 when its kind has none there */
static inline int register_at(const RigStm32TimerState *s, hwaddr offset)
{
    for (int i = 0; i < RIG_TIM_REGS; i++) {
        if (registers[i].offset == offset && writable(s, i)) {
            return i;
        }
    }
    return -1;
}

/* A transfer through TIMx_DMAR: the register the DMA burst reaches now (rig_stm32_timer_burst.c); what it
 * read when not a write */
uint32_t rig_stm32_timer_dmar(RigStm32TimerState *s, bool write, uint32_t value);

#define APB1ENR 0x40
#define APB2ENR 0x44

/* CR1 */
#define CR1_CEN (1u << 0)
#define CR1_UDIS (1u << 1)
#define CR1_URS (1u << 2)
#define CR1_OPM (1u << 3)
#define CR1_DIR (1u << 4)
#define CR1_CMS_SHIFT 5
#define CR1_ARPE (1u << 7)
#define CR2_CCDS (1u << 3) /* the CCx DMA requests at the update event */
#define DIER_DMA_SHIFT 8   /* UDE, CC1DE..CC4DE, COMDE, TDE: the SR flag's bit plus 8 */
/* SR, DIER, EGR */
#define SR_UIF (1u << 0)
#define SR_CCIF(ch) (1u << (1 + (ch)))
#define SR_COMIF (1u << 5)
#define SR_TIF (1u << 6)
#define SR_BIF (1u << 7)
#define SR_CCOF(ch) (1u << (9 + (ch)))
#define EGR_UG (1u << 0)
#define EGR_CCG(ch) (1u << (1 + (ch)))
/* CCMRx: a byte per channel */
#define CCS_OUTPUT 0u
#define CCMR_OCPE (1u << 3)
#define OCM_ACTIVE 1u
#define OCM_INACTIVE 2u
#define OCM_TOGGLE 3u
#define OCM_FORCE_LOW 4u
#define OCM_FORCE_HIGH 5u
#define OCM_PWM1 6u
#define OCM_PWM2 7u
/* CCER: a nibble per channel */
#define CCER_E 1u
#define CCER_P 2u
#define CCER_NE 4u /* (TIM1/TIM8) */
#define CCER_NP 8u
#define BDTR_MOE (1u << 15)
/* SMCR: the slave modes and trigger inputs modelled */
#define SMCR_SMS 7u
#define SMS_RESET 4u
#define SMS_TRIGGER 6u
#define TS_TI1FP1 5u

/* Channel @ch's byte of CCMRx and nibble of CCER, its output compare mode, whether it is an output;
 * CR1.CMS */
static inline unsigned ccmr(const RigStm32TimerState *s, unsigned ch)
{
    return s->regs[ch < 2 ? CCMR1 : CCMR2] >> (8 * (ch % 2)) & 0xFF;
}
static inline unsigned ccer(const RigStm32TimerState *s, unsigned ch) { return s->regs[CCER] >> (4 * ch) & 0xF; }
static inline unsigned oc_mode(const RigStm32TimerState *s, unsigned ch) { return ccmr(s, ch) >> 4 & 0x7; }
static inline bool is_output(const RigStm32TimerState *s, unsigned ch) { return (ccmr(s, ch) & 3) == CCS_OUTPUT; }
static inline unsigned cms(const RigStm32TimerState *s) { return s->regs[CR1] >> CR1_CMS_SHIFT & 3; }

/* The timer's outputs (rig_stm32_timer_out.c): the pins following OCxREF and the output enables, the
 * interrupt lines following SR and DIER, and the pulses latched for the rig at the start of each period */
void rig_stm32_timer_drive(RigStm32TimerState *s);
void rig_stm32_timer_irqs(RigStm32TimerState *s);
void rig_stm32_timer_latch(RigStm32TimerState *s, bool begins);

#endif
