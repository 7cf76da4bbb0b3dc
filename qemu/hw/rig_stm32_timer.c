/*
 * The STM32F405's timers, RM0090 sections 17 (advanced TIM1/TIM8), 18 (TIM2-TIM5), 19 (TIM9-TIM14) and
 * 20 (basic TIM6/TIM7): one model, the registers and bits of each kind of timer a table of data
 * (rig_stm32_timer_regs.h).
 *
 * The counter runs in virtual time on the RCC's APB timer clock (x2 when the APB prescaler is not 1),
 * divided by the prescaler: up, down or center-aligned (CR1.DIR, CMS), with the auto-reload register
 * preloaded under ARPE, PSC taken at each update event (UEV), the repetition counter of the advanced
 * timers, one-pulse mode, UDIS and URS, and EGR.UG. Channels: output compare (frozen, active, inactive,
 * toggle on match, forced levels, PWM modes 1 and 2) with CCRx preloaded under OCxPE, CCxE and CCxP, the
 * advanced timers' complementary outputs (CCxNE, CCxNP; no dead time), BDTR.MOE gating their outputs; input
 * capture (CCxS = 01, 10: the channel's own input or its pair's; CCxP/CCxNP pick rising, falling or both
 * edges; ICxPSC; ICxF is ignored, the edges are clean) with the overcapture flag; the slave mode controller's
 * reset and trigger modes on TI1FP1 and TI2FP2 (PWM input mode: a rising edge captured and restarting the
 * counter). SR's flags are cleared by writing 0; DIER's interrupt enables raise the NVIC lines, the advanced
 * timers' four (BRK, UP, TRG_COM, CC), the others' one; the DMA requests (UDE, CCxDE, COMDE, TDE; CR2.CCDS)
 * go out as pulses on the "dma" lines at their events. The registers answer only with the timer's RCC enable
 * bit on (properties "apb", 1 or 2, and "rcc-bit": APBxENR, APBxRSTR); the RCC's reset bit resets the timer.
 *
 * Nothing runs per tick: reads of CNT compute it from the virtual time, and a QEMU timer is armed for
 * the next event (a compare match, the end of the period) only when something needs its instant: an
 * interrupt or DMA request enabled (any DIER bit), a channel capturing or the slave mode controller on
 * (an edge of the timer's own pins fed back must find CNT at its time), one-pulse mode, an EXTI line with
 * an edge enabled (it may watch a pin of the timer's), or the property "eager" (the reference lazy runs
 * are checked against). Otherwise the events are counted when something looks: a register access, a
 * read of a GPIO port's IDR, and each stop of the rig's link (rig_link_sync_add), so the PWM of motors
 * costs no QEMU timer at all; the pins of such a lazy timer are brought up to date then, while the pulses
 * latched carry each update event's own virtual time (latched-ns, the trace's t_ns). Read over QMP
 * between the link's stops, the properties are those of the last catch-up.
 * The outputs go to the GPIO pins whose AFR selects the timer ("channel-out" lines, four pins per
 * channel), and the pins' levels come back as the channels' inputs ("channel-in").
 *
 * For the rig, each channel's pulse is latched at the start of each period (at the UEV: the CCR, ARR and
 * PSC then in force, in timer-clock ticks), as the AVR tier reads motor pulses from its compare
 * registers: "pulse-ns" GPIO output lines carry each channel's high time in ns when it changes, the
 * read-only QOM properties chC-high-ticks (chCn- for CHxN), period-ticks and clock-hz hold them (latches
 * counts the periods since power-on, latched-ns is the virtual time of the last) (the machine names the
 * timers /machine/tim1 .. /machine/tim14), and with -global rig-stm32f4-timer.trace-pulses=on each
 * change prints a line on stderr:
 *   rig-stm32f4-timer: t_ns=T TIMn chC high_ticks=H period_ticks=P clock_hz=F
 *
 * Not modelled: the other slave modes (gated, encoder, external clock) and triggers (ITRx: timer
 * chaining, TI1F_ED, ETR), hall-sensor mode, dead time, break, COM, ICxF, OCxFE, OCxCE. DMA bursts
 * through DMAR: rig_stm32_timer_burst.c; the outputs, interrupt lines and pulses: rig_stm32_timer_out.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-clock.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/host-utils.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32_timer_regs.h"

static bool clocked(RigStm32TimerState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, s->apb == 1 ? APB1ENR : APB2ENR, s->rcc_bit);
}

/* The timer clock now (the RCC's exact rate; its Clock only tells of changes) */
static uint64_t timer_hz(RigStm32TimerState *s)
{
    return s->rcc ? rig_stm32_rcc_timer_hz(s->rcc, s->apb) : clock_get_hz(s->clk);
}

static uint32_t counter_mask(const RigStm32TimerState *s) { return s->kind->wide ? 0xFFFFFFFFu : C16; }

/* Flags set in SR, and the DMA requests their DIER enables (UDE, CCxDE, COMDE, TDE; RM0090 17.4.4) ask for,
 * sent once the event is handled (settle); CR2.CCDS sends the CCx requests at the update event instead */
static void raise_flags(RigStm32TimerState *s, uint32_t flags)
{
    uint32_t enabled = s->regs[DIER] >> DIER_DMA_SHIFT & 0x7F, requests = flags & enabled;
    s->regs[SR] |= flags;
    if (s->regs[CR2] & CR2_CCDS) {
        requests = (requests & ~0x1Eu) | ((flags & SR_UIF) ? enabled & 0x1Eu : 0);
    }
    s->dma_pending |= requests;
}

/* The update event: the shadow registers take the preloads, UIF unless only software asked and URS
 * says so (RM0090 17.3.1, 17.4.1) */
static void update_event(RigStm32TimerState *s, bool by_software)
{
    if (s->regs[CR1] & CR1_UDIS) {
        return;
    }
    s->arr = s->regs[ARR];
    s->psc = s->regs[PSC];
    for (unsigned ch = 0; ch < s->kind->channels; ch++) {
        if (is_output(s, ch)) {
            s->ccr[ch] = s->regs[CCR1 + ch];
        }
    }
    if (s->kind->advanced) {
        s->repetition = s->regs[RCR];
    }
    if (!(by_software && (s->regs[CR1] & CR1_URS))) {
        raise_flags(s, SR_UIF);
    }
    rig_stm32_timer_latch(s, s->counting); /* (with the counter stopped, the period begins with CEN) */
}

/* A compare match: CCxIF, and the levels of the match modes (RM0090 17.3.8) */
static void compare_match(RigStm32TimerState *s, unsigned ch)
{
    unsigned mode = oc_mode(s, ch), center = cms(s);
    if ((center == 1 && !s->down) || (center == 2 && s->down)) { /* CMS 01: flags counting down only */
        return;
    }
    raise_flags(s, SR_CCIF(ch));
    if (mode == OCM_ACTIVE || mode == OCM_INACTIVE) {
        s->ref[ch] = mode == OCM_ACTIVE;
    } else if (mode == OCM_TOGGLE) {
        s->ref[ch] = !s->ref[ch];
    }
}

/* Counter steps to the next boundary (overflow or underflow) from CNT, in the current direction */
static uint64_t steps_to_boundary(const RigStm32TimerState *s)
{
    uint64_t cnt = s->regs[CNT], arr = s->arr;
    if (cms(s)) {
        return s->down ? (cnt ? cnt : 1) : (arr > cnt ? arr - cnt : 1);
    }
    return s->down ? cnt + 1 : (arr >= cnt ? arr - cnt + 1 : (uint64_t)counter_mask(s) - cnt + 1 + arr + 1);
}

/* Counter steps to the next compare match of a channel in use, or to the boundary if sooner */
static uint64_t steps_to_event(const RigStm32TimerState *s)
{
    uint64_t best = steps_to_boundary(s), cnt = s->regs[CNT];
    for (unsigned ch = 0; ch < s->kind->channels; ch++) {
        uint64_t ccr = s->ccr[ch];
        if (!is_output(s, ch)) {
            continue;
        }
        uint64_t d = s->down ? (cnt > ccr ? cnt - ccr : 0) : (ccr > cnt ? ccr - cnt : 0);
        if (d > 0 && d < best) {
            best = d;
        }
    }
    return best;
}

/* The end of a counting period: the repetition counter, then the UEV; one-pulse mode stops there */
static void boundary(RigStm32TimerState *s)
{
    if (s->kind->advanced && s->repetition > 0) {
        s->repetition--;
        return;
    }
    update_event(s, false);
    if (s->regs[CR1] & CR1_OPM) {
        s->regs[CR1] &= ~CR1_CEN;
    }
}

/* @steps counter steps from the current state, every match and boundary on the way taken in order:
 * whether there was any */
static bool count(RigStm32TimerState *s, uint64_t steps)
{
    uint32_t mask = counter_mask(s);
    bool events = false;
    while (steps > 0 && (s->regs[CR1] & CR1_CEN) && s->arr != 0) {
        uint64_t d = steps_to_event(s);
        if (steps < d) {
            s->regs[CNT] = (s->down ? s->regs[CNT] - steps : s->regs[CNT] + steps) & mask;
            return events;
        }
        bool at_boundary = d == steps_to_boundary(s);
        steps -= d;
        events = true;
        s->regs[CNT] = (s->down ? s->regs[CNT] - d : s->regs[CNT] + d) & mask;
        if (at_boundary) {
            if (cms(s)) {
                s->down = !s->down; /* at ARR it turns down (overflow), at 0 up (underflow) */
            } else {
                s->regs[CNT] = s->down ? s->arr : 0;
            }
            boundary(s);
        }
        for (unsigned ch = 0; ch < s->kind->channels; ch++) {
            if (is_output(s, ch) && s->regs[CNT] == s->ccr[ch]) {
                compare_match(s, ch);
            }
        }
    }
    return events;
}

/* The first virtual ns at which catch_up() has counted @ticks timer-clock ticks since base_ns */
static int64_t tick_ns(const RigStm32TimerState *s, unsigned __int128 ticks)
{
    unsigned __int128 ns = (ticks * NANOSECONDS_PER_SECOND + s->hz - 1) / s->hz;
    return s->base_ns + (int64_t)MIN(ns, (unsigned __int128)INT64_MAX / 2);
}

/* Brings the counter to the present: the timer-clock ticks since the last sync, through the prescaler,
 * each event at the time of its tick (event_ns, now for what software does after); whether an event (a
 * match, a boundary) came on the way */
static bool catch_up(RigStm32TimerState *s)
{
    bool events = false;
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    s->event_ns = now;
    if (!s->counting) {
        return false;
    }
    uint64_t total = muldiv64(now - s->base_ns, (uint32_t)s->hz, NANOSECONDS_PER_SECOND);
    uint64_t ticks = total - s->ticks_done;
    s->ticks_done = total;
    while (ticks > 0 && (s->regs[CR1] & CR1_CEN) && s->arr != 0) { /* a null ARR blocks the counter */
        uint64_t div = (uint64_t)s->psc + 1, to_step = div - s->prescaler;
        if (ticks < to_step) {
            s->prescaler += ticks;
            break;
        }
        ticks -= to_step;
        s->prescaler = 0;
        /* this step and the whole steps that fit before the next event (where PSC may change) */
        uint64_t more = MIN(ticks / div, steps_to_event(s) - 1);
        ticks -= more * div;
        s->event_ns = tick_ns(s, total - ticks); /* (an event comes only at the last step) */
        events |= count(s, 1 + more);
    }
    s->event_ns = now;
    if (!(s->regs[CR1] & CR1_CEN)) {
        s->counting = false;
    }
    return events;
}

/* Whether something sees the timer's events at their instants (the head comment): with none, they wait
 * for the next catch-up */
static bool needs_instant(const RigStm32TimerState *s)
{
    if (s->eager || s->regs[DIER] || (s->regs[CR1] & CR1_OPM) || (s->regs[SMCR] & SMCR_SMS) ||
        rig_stm32_exti_watches_pins()) {
        return true;
    }
    for (unsigned ch = 0; ch < s->kind->channels; ch++) {
        if (!is_output(s, ch) && (ccer(s, ch) & CCER_E)) {
            return true;
        }
    }
    return false;
}

/* Arms the QEMU timer for the next event, when the counter runs and the event needs its instant */
static void schedule(RigStm32TimerState *s)
{
    if (!s->counting || s->arr == 0 || s->hz == 0 || !needs_instant(s)) {
        timer_del(s->timer);
        return;
    }
    uint64_t div = (uint64_t)s->psc + 1;
    int64_t deadline = tick_ns(s, s->ticks_done + (div - s->prescaler) + (steps_to_event(s) - 1) * div);
    /* (an unchanged deadline is left armed: re-arming it takes the timer out of QEMU's list and back, which
     * with the core asleep makes QEMU warp virtual time to the earliest deadline; the link's stop holds
     * the earliest deadline while it lasts, so that warp goes nowhere, but costs a notification) */
    if (!timer_pending(s->timer) || timer_expire_time_ns(s->timer) != deadline) {
        timer_mod(s->timer, deadline);
    }
}

/* After a change: the pins, the interrupt lines, the DMA requests (a pulse each; the DMA may write this
 * timer's registers, settling it again), then the next event. Under -icount with the core asleep, arming
 * the QEMU timer moves virtual time on to its deadline at once, so it comes last and once, after what the
 * DMA and the pins (back as the channels' inputs) did */
static void settle(RigStm32TimerState *s)
{
    bool outermost = !s->settling;
    uint8_t requests = s->dma_pending;
    s->dma_pending = 0;
    s->dma_sent = requests ? requests : s->dma_sent; /* (a DMAR burst goes on with them) */
    s->settling = true;
    rig_stm32_timer_drive(s);
    rig_stm32_timer_irqs(s);
    for (unsigned k = 0; k < RIG_DMA_TIM_REQS; k++) {
        if (requests >> k & 1) {
            qemu_irq_pulse(s->dma[k]);
        }
    }
    if (outermost) {
        s->settling = false;
        schedule(s);
    }
}

static void tim_event(void *opaque)
{
    RigStm32TimerState *s = opaque;
    catch_up(s);
    settle(s);
}

/* Every timer of the machine, by index, for the syncs */
static RigStm32TimerState *timers[15];

void rig_stm32_timers_sync(bool rearm)
{
    for (unsigned n = 1; n < ARRAY_SIZE(timers); n++) {
        RigStm32TimerState *s = timers[n];
        if (s != NULL && (catch_up(s) || rearm)) {
            settle(s);
        }
    }
}

/* The link's stop: the pulses it reads are those of the events up to now */
static void timers_link_sync(void *opaque) { rig_stm32_timers_sync(false); }

/* Starts counting from now (CEN set, or a new clock) */
static void start_counting(RigStm32TimerState *s)
{
    s->counting = (s->regs[CR1] & CR1_CEN) && s->hz > 0;
    s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    s->ticks_done = 0;
}

/* Input capture on channel @ch (RM0090 17.3.5): CNT into CCRx, CCxIF, CCxOF if CCxIF was still set */
static void capture(RigStm32TimerState *s, unsigned ch)
{
    unsigned psc = ccmr(s, ch) >> 2 & 3;
    if (++s->capture_count[ch] < (1u << psc)) {
        return;
    }
    s->capture_count[ch] = 0;
    if (s->regs[SR] & SR_CCIF(ch)) {
        s->regs[SR] |= SR_CCOF(ch);
    }
    s->regs[CCR1 + ch] = s->regs[CNT];
    raise_flags(s, SR_CCIF(ch));
}

/* EGR.UG, or a reset trigger: the counter and prescaler restart, then the UEV (RM0090 17.3.1) */
static void reinitialize(RigStm32TimerState *s)
{
    s->prescaler = 0;
    s->down = !cms(s) && (s->regs[CR1] & CR1_DIR);
    if (s->kind->advanced) {
        s->repetition = s->regs[RCR];
    }
    update_event(s, true);
    s->regs[CNT] = s->down ? s->arr : 0;
    if (s->counting) {
        start_counting(s);
    }
}

/* Whether CCxP/CCxNP of channel @ch (00 rising, 01 falling, 11 both) select the edge to @level: for its
 * capture, and for TIxFPx as the slave mode controller's trigger */
static bool edge_selected(const RigStm32TimerState *s, unsigned ch, int level)
{
    unsigned edge = (ccer(s, ch) & CCER_P ? 1 : 0) | (ccer(s, ch) & CCER_NP ? 2 : 0);
    return edge == 3 || (edge == 0 && level) || (edge == 1 && !level);
}

/* The slave mode controller on TI1FP1 or TI2FP2 (RM0090 18.3.14, SMCR.TS 101 and 110): reset mode
 * reinitializes the counter with an update of the registers (the PWM input mode of 18.3.6), trigger
 * mode starts it; both set TIF */
static void trigger_input(RigStm32TimerState *s, unsigned line, int level)
{
    unsigned sms = s->regs[SMCR] & SMCR_SMS, ts = s->regs[SMCR] >> 4 & 7;
    if ((sms != SMS_RESET && sms != SMS_TRIGGER) || line > 1 || ts != TS_TI1FP1 + line ||
        !edge_selected(s, line, level)) {
        return;
    }
    raise_flags(s, SR_TIF);
    if (sms == SMS_RESET) {
        reinitialize(s);
    } else if (!(s->regs[CR1] & CR1_CEN)) {
        s->regs[CR1] |= CR1_CEN;
        start_counting(s);
    }
}

/* A channel's pin changed (line: channel): the channels that take it as their input capture the edges
 * they select, then the slave mode controller sees it */
static void channel_input(void *opaque, int line, int level)
{
    RigStm32TimerState *s = opaque;
    if (line >= s->kind->channels || s->input[line] == (level != 0)) {
        return;
    }
    s->input[line] = level != 0;
    catch_up(s);
    for (unsigned ch = 0; ch < s->kind->channels; ch++) {
        unsigned ccs = ccmr(s, ch) & 3, source = ccs == 1 ? ch : (ch ^ 1);
        if (ccs != 0 && ccs != 3 && source == (unsigned)line && (ccer(s, ch) & CCER_E) && edge_selected(s, ch, level)) {
            capture(s, ch);
        }
    }
    trigger_input(s, line, level);
    settle(s);
}

static void clock_changes(void *opaque, ClockEvent event)
{
    RigStm32TimerState *s = opaque;
    if (event == ClockPreUpdate) {
        catch_up(s); /* the ticks at the old rate */
    } else {
        s->hz = timer_hz(s);
        if (s->counting || (s->regs[CR1] & CR1_CEN)) {
            start_counting(s);
        }
        settle(s); /* (what the old rate's last ticks changed, and the next event at the new rate) */
    }
}

static void event_generation(RigStm32TimerState *s, uint32_t egr)
{
    if (egr & EGR_UG) {
        reinitialize(s);
    }
    for (unsigned ch = 0; ch < s->kind->channels; ch++) {
        if (egr & EGR_CCG(ch)) {
            if (is_output(s, ch)) {
                raise_flags(s, SR_CCIF(ch));
            } else {
                capture(s, ch);
            }
        }
    }
    raise_flags(s, egr & (SR_COMIF | SR_TIF | SR_BIF));
}

static uint64_t tim_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32TimerState *s = opaque;
    int i = register_at(s, offset);
    if (!clocked(s)) {
        return 0;
    }
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-timer: TIM%u: read of reserved offset 0x%" HWADDR_PRIx "\n",
                      s->index, offset);
        return 0;
    }
    bool changed = catch_up(s); /* (a poll may come before the event's timer: the pins follow now) */
    if (i >= CCR1 && i <= CCR4 && !is_output(s, i - CCR1)) {
        s->regs[SR] &= ~SR_CCIF(i - CCR1); /* reading a capture clears its flag */
        changed = true;
    }
    if (changed) {
        settle(s);
    }
    if (i == CR1) { /* DIR: as the counter goes (read-only when center-aligned) */
        return (s->regs[CR1] & ~CR1_DIR) | (s->down ? CR1_DIR : 0);
    }
    return i == EGR ? 0 : i == DMAR ? rig_stm32_timer_dmar(s, false, 0) : s->regs[i];
}

static void tim_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32TimerState *s = opaque;
    int i = register_at(s, offset);
    uint32_t v = (uint32_t)value & (i >= 0 ? writable(s, i) : 0);
    if (!clocked(s)) {
        return;
    }
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-timer: TIM%u: write of reserved offset 0x%" HWADDR_PRIx "\n",
                      s->index, offset);
        return;
    }
    catch_up(s);
    bool was_enabled = s->regs[CR1] & CR1_CEN;
    switch (i) {
    case SR: /* rc_w0: writing 0 clears a flag, 1 leaves it */
        s->regs[SR] &= v | ~writable(s, SR);
        break;
    case EGR:
        event_generation(s, v);
        break;
    case CR1:
        s->regs[CR1] = v;
        if (!cms(s)) {
            s->down = v & CR1_DIR;
        }
        if (!(v & CR1_CEN)) {
            s->counting = false;
        } else if (!was_enabled) {
            start_counting(s);
            rig_stm32_timer_latch(s, true);
        }
        break;
    case ARR:
        s->regs[ARR] = v;
        if (!(s->regs[CR1] & CR1_ARPE)) {
            s->arr = v;
        }
        break;
    case CCR1:
    case CCR2:
    case CCR3:
    case CCR4:
        if (is_output(s, i - CCR1)) { /* read-only in input capture mode */
            s->regs[i] = v;
            if (!(ccmr(s, i - CCR1) & CCMR_OCPE)) {
                s->ccr[i - CCR1] = v;
            }
        }
        break;
    case CCER:
        for (unsigned ch = 0; ch < s->kind->channels; ch++) {
            if (!(v >> (4 * ch) & CCER_E)) {
                s->capture_count[ch] = 0; /* the input prescaler restarts while the capture is off */
            }
        }
        s->regs[CCER] = v;
        break;
    case DMAR:
        rig_stm32_timer_dmar(s, true, (uint32_t)value);
        break;
    default:
        s->regs[i] = v;
    }
    settle(s);
}

static const MemoryRegionOps tim_ops = {
    .read = tim_read,
    .write = tim_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void tim_reset(DeviceState *dev)
{
    RigStm32TimerState *s = RIG_STM32_TIMER(dev);
    memset(s->regs, 0, sizeof(s->regs));
    memset(s->ccr, 0, sizeof(s->ccr));
    memset(s->ref, 0, sizeof(s->ref));
    memset(s->capture_count, 0, sizeof(s->capture_count));
    memset(s->pulse_ticks, 0, sizeof(s->pulse_ticks));
    memset(s->out, -2, sizeof(s->out));
    s->arr = s->psc = s->prescaler = s->repetition = s->period_ticks = s->latched_hz = 0;
    s->down = s->counting = false;
    s->dma_pending = s->dma_sent = s->burst = 0;
    s->settling = false;
    s->hz = timer_hz(s);
    timer_del(s->timer);
    rig_stm32_timer_drive(s);
    rig_stm32_timer_irqs(s);
}

static void tim_realize(DeviceState *dev, Error **errp)
{
    RigStm32TimerState *s = RIG_STM32_TIMER(dev);
    if (s->index < 1 || s->index > 14 || s->apb < 1 || s->apb > 2) {
        error_setg(errp, "rig-stm32f4-timer: index is 1..14 (TIMn), apb 1 or 2; not %u and %u", s->index, s->apb);
        return;
    }
    if (timers[s->index] != NULL) {
        error_setg(errp, "rig-stm32f4-timer: a second TIM%u", s->index);
        return;
    }
    s->kind = &kinds[kind_of[s->index]];
    s->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, tim_event, s);
    bool first = true;
    for (unsigned n = 1; n < ARRAY_SIZE(timers); n++) {
        first &= timers[n] == NULL;
    }
    if (first) {
        rig_link_sync_add(timers_link_sync, NULL);
    }
    timers[s->index] = s;
}

static void tim_instance_init(Object *obj)
{
    RigStm32TimerState *s = RIG_STM32_TIMER(obj);
    memory_region_init_io(&s->iomem, obj, &tim_ops, s, TYPE_RIG_STM32_TIMER, 0x400);
    s->iomem.disable_reentrancy_guard = true; /* the DMA a register write asked for writes CCRx (settle) */
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    for (unsigned k = 0; k < RIG_TIM_IRQS; k++) {
        sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq[k]);
    }
    s->clk = qdev_init_clock_in(DEVICE(obj), "clk", clock_changes, s, ClockPreUpdate | ClockUpdate);
    qdev_init_gpio_out_named(DEVICE(obj), s->channel_out, "channel-out", RIG_TIM_OUTPUTS * RIG_TIM_PINS_PER_CHANNEL);
    qdev_init_gpio_in_named(DEVICE(obj), channel_input, "channel-in", RIG_TIM_CHANNELS);
    qdev_init_gpio_out_named(DEVICE(obj), s->pulse_ns, "pulse-ns", RIG_TIM_OUTPUTS);
    qdev_init_gpio_out_named(DEVICE(obj), s->dma, "dma", RIG_DMA_TIM_REQS);
    /* the latched pulses as read-only QOM properties too (QMP qom-get /machine/timN chC-high-ticks) */
    static const char *const high_names[RIG_TIM_OUTPUTS] = {
        "ch1-high-ticks",  "ch2-high-ticks",  "ch3-high-ticks",  "ch4-high-ticks",
        "ch1n-high-ticks", "ch2n-high-ticks", "ch3n-high-ticks",
    };
    for (unsigned o = 0; o < RIG_TIM_OUTPUTS; o++) {
        object_property_add_uint32_ptr(obj, high_names[o], &s->pulse_ticks[o], OBJ_PROP_FLAG_READ);
    }
    object_property_add_uint32_ptr(obj, "period-ticks", &s->period_ticks, OBJ_PROP_FLAG_READ);
    object_property_add_uint64_ptr(obj, "clock-hz", &s->latched_hz, OBJ_PROP_FLAG_READ);
    /* how many periods have started since power-on (a reset keeps counting), and when the last did: each
     * a pulse at the pins of the channels in PWM */
    object_property_add_uint64_ptr(obj, "latches", &s->latches, OBJ_PROP_FLAG_READ);
    object_property_add_uint64_ptr(obj, "latched-ns", &s->latched_ns, OBJ_PROP_FLAG_READ);
}

static Property tim_properties[] = {
    DEFINE_PROP_UINT8("index", RigStm32TimerState, index, 0),
    DEFINE_PROP_UINT8("apb", RigStm32TimerState, apb, 0),
    DEFINE_PROP_UINT8("rcc-bit", RigStm32TimerState, rcc_bit, 0),
    DEFINE_PROP_BOOL("trace-pulses", RigStm32TimerState, trace_pulses, false),
    DEFINE_PROP_BOOL("eager", RigStm32TimerState, eager, false),
    DEFINE_PROP_LINK("rcc", RigStm32TimerState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void tim_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = tim_reset;
    dc->realize = tim_realize;
    device_class_set_props(dc, tim_properties);
}

static const TypeInfo tim_info = {
    .name = TYPE_RIG_STM32_TIMER,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32TimerState),
    .instance_init = tim_instance_init,
    .class_init = tim_class_init,
};

static void tim_register_types(void) { type_register_static(&tim_info); }

type_init(tim_register_types)
