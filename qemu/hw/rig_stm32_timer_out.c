/*
 * The STM32F405 timers' outputs (the model: rig_stm32_timer.c): the channels' levels at their pins
 * (OCxREF through CCxE/CCxP, the complementary outputs, MOE), the NVIC lines from SR and DIER, and each
 * channel's pulse latched for the rig at the start of each period.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "qemu/host-utils.h"
#include "qemu/timer.h"
#include "rig_stm32_timer_regs.h"

/* OCxREF of a PWM mode as a function of the counter (RM0090 17.3.10): mode 1 active while CNT < CCR
 * counting up, while CNT <= CCR counting down; mode 2 the opposite */
static bool pwm_ref(const RigStm32TimerState *s, unsigned ch)
{
    uint32_t cnt = s->regs[CNT], ccr = s->ccr[ch];
    bool active = s->down ? cnt <= ccr : cnt < ccr;
    return oc_mode(s, ch) == OCM_PWM1 ? active : !active;
}

/* Whether output @o (OC1..OC4 as 0..3, the advanced timers' OC1N..OC3N as 4..6) exists */
static bool has_output(const RigStm32TimerState *s, unsigned o)
{
    return o < s->kind->channels || (s->kind->advanced && o < RIG_TIM_OUTPUTS);
}

/* Output @o's level for OCxREF = @ref: OCx drives with CCxE, through CCxP; OCxN with CCxNE, through CCxNP, the
 * complement of OCxREF while OCx is on too (RM0090 17.3.11, dead time taken as 0); on TIM1/TIM8 only
 * with BDTR.MOE. Off, an output lets go of its pins (18.4.9: OCx_EN = 0): RIG_GPIO_AF_RELEASED */
static int output_level(const RigStm32TimerState *s, unsigned o, bool ref)
{
    unsigned ch = o % RIG_TIM_CHANNELS, bits = ccer(s, ch);
    bool n = o >= RIG_TIM_CHANNELS;
    if (!is_output(s, ch) || !(bits & (n ? CCER_NE : CCER_E)) || (s->kind->advanced && !(s->regs[BDTR] & BDTR_MOE))) {
        return RIG_GPIO_AF_RELEASED;
    }
    bool invert = n ? !!(bits & CCER_NP) ^ !!(bits & CCER_E) : !!(bits & CCER_P);
    return ref ^ invert;
}

/* The pins follow each output */
void rig_stm32_timer_drive(RigStm32TimerState *s)
{
    for (unsigned ch = 0; ch < s->kind->channels; ch++) {
        unsigned mode = oc_mode(s, ch);
        if (is_output(s, ch)) {
            if (mode == OCM_PWM1 || mode == OCM_PWM2) {
                s->ref[ch] = pwm_ref(s, ch);
            } else if (mode == OCM_FORCE_LOW || mode == OCM_FORCE_HIGH) {
                s->ref[ch] = mode == OCM_FORCE_HIGH;
            }
        }
    }
    for (unsigned o = 0; o < RIG_TIM_OUTPUTS; o++) {
        int level = has_output(s, o) ? output_level(s, o, s->ref[o % RIG_TIM_CHANNELS]) : RIG_GPIO_AF_RELEASED;
        if (level != s->out[o]) {
            s->out[o] = level;
            for (unsigned pin = 0; pin < RIG_TIM_PINS_PER_CHANNEL; pin++) {
                qemu_set_irq(s->channel_out[o * RIG_TIM_PINS_PER_CHANNEL + pin], level);
            }
        }
    }
}

void rig_stm32_timer_irqs(RigStm32TimerState *s)
{
    uint32_t pending = s->regs[SR] & s->regs[DIER] & 0xFF;
    bool line[RIG_TIM_IRQS] = {
        [RIG_TIM_IRQ_BRK] = pending & SR_BIF,
        [RIG_TIM_IRQ_UP] = pending & SR_UIF,
        [RIG_TIM_IRQ_TRG_COM] = pending & (SR_TIF | SR_COMIF),
        [RIG_TIM_IRQ_CC] = pending & 0x1E,
    };
    if (s->kind->advanced) {
        for (unsigned k = 0; k < RIG_TIM_IRQS; k++) {
            qemu_set_irq(s->irq[k], line[k]);
        }
    } else {
        qemu_set_irq(s->irq[0], pending != 0);
    }
}

/* High ticks of the timer clock per period at output @o's pins, for a channel in PWM mode (0 otherwise) */
static uint32_t pulse_ticks(const RigStm32TimerState *s, unsigned o, uint32_t period)
{
    unsigned ch = o % RIG_TIM_CHANNELS, mode = oc_mode(s, ch);
    uint64_t arr = s->arr, ccr = s->ccr[ch], active;
    int level_while_active = output_level(s, o, true);
    if ((mode != OCM_PWM1 && mode != OCM_PWM2) || level_while_active == RIG_GPIO_AF_RELEASED) {
        return 0;
    }
    if (cms(s)) {
        active = 2 * MIN(ccr, arr);
    } else if (s->down) {
        active = MIN(ccr, arr) + 1;
    } else {
        active = MIN(ccr, arr + 1);
    }
    uint64_t counts = cms(s) ? 2 * arr : arr + 1;
    active = (mode == OCM_PWM1 ? active : counts - active) * ((uint64_t)s->psc + 1);
    return level_while_active ? (uint32_t)active : period - (uint32_t)active;
}

/* The pulses for the rig: latched at the start of each period (@begins: a period of the counter begins
 * here, counted in latches; an update event with the counter stopped, the set-up's EGR.UG, only takes the
 * values: its period begins when CEN starts the counter), sent and traced when they change */
void rig_stm32_timer_latch(RigStm32TimerState *s, bool begins)
{
    uint64_t counts = cms(s) ? 2 * (uint64_t)s->arr : (uint64_t)s->arr + 1;
    uint32_t period = (uint32_t)MIN(counts * ((uint64_t)s->psc + 1), UINT32_MAX);
    for (unsigned o = 0; o < RIG_TIM_OUTPUTS; o++) {
        uint32_t high = has_output(s, o) ? pulse_ticks(s, o, period) : 0;
        /* (an output without pulses stays silent while only the period or the clock changes) */
        if (high == s->pulse_ticks[o] && ((period == s->period_ticks && s->hz == s->latched_hz) || high == 0)) {
            continue;
        }
        s->pulse_ticks[o] = high;
        qemu_set_irq(s->pulse_ns[o], s->hz ? (int)muldiv64(high, NANOSECONDS_PER_SECOND, s->hz) : 0);
        if (s->trace_pulses) {
            fprintf(stderr,
                    "rig-stm32f4-timer: t_ns=%" PRId64 " TIM%u ch%u%s high_ticks=%" PRIu32 " period_ticks=%" PRIu32
                    " clock_hz=%" PRIu64 "\n",
                    s->event_ns, s->index, o % RIG_TIM_CHANNELS + 1, o >= RIG_TIM_CHANNELS ? "n" : "", high, period,
                    s->hz);
        }
    }
    s->period_ticks = period;
    s->latched_hz = s->hz;
    if (begins) {
        s->latches++;
        s->latched_ns = (uint64_t)s->event_ns;
    }
}
