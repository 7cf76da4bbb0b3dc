/* Motor pulses as the pin shows them (glue.h). A motor on a timer's compare output, while the compare unit
 * drives the pin, gets its pulse from the timer's registers as the hardware latches them: at BOTTOM in fast PWM and phase and frequency correct
 * PWM, at TOP in phase correct PWM (the datasheets' "Update of OCRnx at"), by a glue event at each latch
 * point, so a compare value written between two latches lands exactly where the hardware puts it. simavr
 * 1.6 is not used for this: it lacks the phase correct modes and drives no pin edges in the modes it has as
 * phase correct. Widths, with P the prescaler's cycles per count and TOP the mode's:
 *   fast PWM, non-inverting: (OCR + 1) P, period (TOP + 1) P; inverting: (TOP - OCR) P
 *   phase correct, non-inverting: 2 OCR P centred on BOTTOM, period 2 TOP P
 *   phase and frequency correct, non-inverting: (OCR before BOTTOM + OCR after) P, period 2 TOP P
 * A pin that is not an output (its DDR bit clear) gives no timer pulse. With its compare output
 * disconnected (COMnx = 0, or 1 outside the toggle modes) the datasheets' words are "normal port operation,
 * OCnx disconnected": the pin follows PORTx, and the motor is measured from its edges, as a motor without
 * a timer always is (software PWM). */
#include <string.h>

#include <simavr/avr_ioport.h>
#include <simavr/sim_io.h>

#include "glue.h"

enum { NONE, FAST, PC, PFC };
enum { FIXED, ICR, OCRA };

typedef struct {
    uint8_t kind, top_from;
    uint16_t top;
} mode_t_;

static mode_t_ mode_of(const mcu_timer *tm)
{
    static const mode_t_ wide[16] = {
        [1] = { PC, FIXED, 0xFF },   [2] = { PC, FIXED, 0x1FF },   [3] = { PC, FIXED, 0x3FF },
        [5] = { FAST, FIXED, 0xFF }, [6] = { FAST, FIXED, 0x1FF }, [7] = { FAST, FIXED, 0x3FF },
        [8] = { PFC, ICR, 0 },       [9] = { PFC, OCRA, 0 },       [10] = { PC, ICR, 0 },
        [11] = { PC, OCRA, 0 },      [14] = { FAST, ICR, 0 },      [15] = { FAST, OCRA, 0 },
    };
    static const mode_t_ narrow[8] = {
        [1] = { PC, FIXED, 0xFF },
        [3] = { FAST, FIXED, 0xFF },
        [5] = { PC, OCRA, 0 },
        [7] = { FAST, OCRA, 0 },
    };
    return tm->wide ? wide[tm->mode & 15] : narrow[tm->mode & 7];
}

static uint16_t reg(const mcu_engine *e, const mcu_timer *tm, uint16_t addr)
{
    const uint8_t *d = e->avr->data;
    return tm->wide ? (uint16_t)(d[addr] | d[addr + 1] << 8) : d[addr];
}

static uint32_t prescale(const mcu_timer *tm)
{
    static const uint32_t common[8] = { 0, 1, 8, 64, 256, 1024, 0, 0 }; /* 6, 7: an external clock */
    static const uint32_t timer2[8] = { 0, 1, 8, 32, 64, 128, 256, 1024 };
    return tm->n == 2 ? timer2[tm->cs] : common[tm->cs];
}

static void push(mcu_engine *e, mcu_motor *m, mcu_pulse p)
{
    if (m->n_out == MCU_PULSES) {
        memmove(m->out, m->out + 1, (MCU_PULSES - 1) * sizeof m->out[0]);
        m->n_out--;
        m->dropped++;
    }
    m->out[m->n_out++] = p;
    e->last_activity = e->avr->cycle;
}

/* the pending pulse, when it has ended by `now` (else dropped when `drop`) */
static void flush(mcu_engine *e, mcu_motor *m, uint64_t now, bool drop)
{
    if (!m->has_pending)
        return;
    if (m->pending.rise + m->pending.width <= now) {
        m->from_timer++;
        push(e, m, m->pending);
        m->has_pending = false;
    } else if (drop) {
        m->has_pending = false;
    }
}

static uint16_t top_of(const mcu_engine *e, const mcu_timer *tm, mode_t_ md)
{
    uint16_t top = md.top_from == FIXED ? md.top : reg(e, tm, md.top_from == ICR ? tm->icr : tm->ocr[0]);
    return top ? top : 1;
}

/* one latch point of one timer, at tm->next */
static void step(mcu_engine *e, mcu_timer *tm)
{
    const uint8_t *d = e->avr->data;
    uint64_t now = tm->next, P = prescale(tm);
    mode_t_ md = mode_of(tm);
    uint64_t T = top_of(e, tm, md);
    bool top_event = md.kind == PC && tm->phase == 1;
    tm->events++;
    for (int i = 0; i < e->n_motors; i++) {
        mcu_motor *m = &e->motors[i];
        if (m->timer != tm->n || (md.kind == PC && !top_event))
            continue;
        flush(e, m, now, false);
        uint8_t com = (uint8_t)(d[tm->tccra] >> (6 - 2 * m->channel) & 3);
        uint64_t o = reg(e, tm, tm->ocr[m->channel]);
        o = o < T ? o : T;
        bool out = (d[m->ddr] >> m->bit & 1) && com >= 2;
        mcu_pulse p = { 0, 0, 0 };
        if (md.kind == FAST) {
            p = com == 2 ? (mcu_pulse){ now, (o + 1) * P, (T + 1) * P }
                         : (mcu_pulse){ now + (o + 1) * P, (T - o) * P, (T + 1) * P };
        } else if (md.kind == PC) {
            p = (mcu_pulse){ now + (T - o) * P, 2 * o * P, 2 * T * P };
            out = out && com == 2;
        } else {
            if (m->has_prev)
                p = (mcu_pulse){ now - m->ocr_prev * P, (m->ocr_prev + o) * P, 2 * T * P };
            out = out && com == 2 && m->has_prev;
            m->ocr_prev = (uint16_t)o;
            m->has_prev = true;
        }
        if (out && p.width > 0) {
            m->pending = p;
            m->has_pending = true;
        }
    }
    if (md.kind == FAST) {
        tm->next = now + (T + 1) * P;
    } else if (md.kind == PC) {
        tm->next = now + T * P;
        tm->phase ^= 1;
    } else {
        tm->next = now + 2 * T * P;
    }
}

/* the timer's mode or clock changed (a TCCRnA/B write): it starts again from BOTTOM now */
static void reconfigure(mcu_engine *e, mcu_timer *tm)
{
    const uint8_t *d = e->avr->data;
    uint8_t a = d[tm->tccra], b = d[tm->tccrb];
    uint8_t mode = (uint8_t)((a & 3) | (tm->wide ? (b >> 3 & 3) << 2 : (b >> 3 & 1) << 2));
    uint8_t cs = b & 7;
    if (mode == tm->mode && cs == tm->cs)
        return;
    tm->mode = mode;
    tm->cs = cs;
    for (int i = 0; i < e->n_motors; i++)
        if (e->motors[i].timer == tm->n) {
            flush(e, &e->motors[i], e->avr->cycle, true);
            e->motors[i].has_prev = false;
        }
    tm->phase = 0;
    tm->next = prescale(tm) && mode_of(tm).kind != NONE ? e->avr->cycle : MCU_NEVER;
    mcu_reschedule(e);
}

static void wrapped_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    mcu_wrap *w = param;
    if (w->c)
        w->c(avr, addr, v, w->param);
    else
        avr->data[addr] = v;
    reconfigure(w->engine, w->timer);
}

static void wrap(mcu_engine *e, mcu_timer *tm, uint16_t addr)
{
    mcu_wrap *w = &e->wraps[e->n_wraps++];
    int io = AVR_DATA_TO_IO(addr);
    *w = (mcu_wrap){ e, tm, e->avr->io[io].w.c, e->avr->io[io].w.param };
    e->avr->io[io].w.c = wrapped_write;
    e->avr->io[io].w.param = w;
}

/* a timer's registers (data-space addresses, from engine.py's tables); once per timer */
MCU_API void mcu_timer_define(mcu_engine *e, uint8_t n, bool wide, uint16_t tccra, uint16_t tccrb, uint16_t tcnt,
                              uint16_t icr, uint16_t ocra, uint16_t ocrb, uint16_t ocrc)
{
    mcu_timer *tm = &e->timers[n];
    if (tm->used || n > 5)
        return;
    *tm = (mcu_timer){ .used = true,
                       .n = n,
                       .wide = wide,
                       .tccra = tccra,
                       .tccrb = tccrb,
                       .tcnt = tcnt,
                       .icr = icr,
                       .ocr = { ocra, ocrb, ocrc },
                       .next = MCU_NEVER };
    wrap(e, tm, tccra);
    wrap(e, tm, tccrb);
    reconfigure(e, tm);
}

/* the compare unit drives the motor's pin (else the port does). The COMnx bits, as the timer chapters'
 * "Compare Output Mode" tables give them (2549Q; the 328P's alike): 0 "normal port operation, OCnx
 * disconnected"; 2, 3 the compare output in every mode; 1 toggles OCnx in the non-PWM modes, and in the
 * PWM modes only OCnA's, with WGM 14, 15 (fast PWM), 9, 11 (phase correct) on a 16-bit timer, WGMn2 = 1
 * on an 8-bit one (TOP = OCRnA) */
static bool compare_drives(const mcu_engine *e, const mcu_motor *m)
{
    const mcu_timer *tm = &e->timers[m->timer];
    uint8_t com = (uint8_t)(e->avr->data[tm->tccra] >> (6 - 2 * m->channel) & 3);
    mode_t_ md = mode_of(tm);
    if (com != 1)
        return com != 0;
    if (md.kind == NONE)
        return true;
    return m->channel == 0 && (md.top_from == OCRA || (md.kind == FAST && md.top_from == ICR));
}

static void pin_changed(struct avr_irq_t *irq, uint32_t value, void *param)
{
    mcu_motor *m = param;
    mcu_engine *e = m->engine;
    uint64_t now = e->avr->cycle;
    if (m->timer >= 0 && compare_drives(e, m)) { /* its pulses are the registers' */
        m->edge_rise = m->edge_prev_rise = MCU_NEVER;
        return;
    }
    if (value && !irq->value) {
        m->edge_prev_rise = m->edge_rise;
        m->edge_rise = now;
    } else if (!value && irq->value && m->edge_rise != MCU_NEVER) {
        uint64_t period = m->edge_prev_rise == MCU_NEVER ? 0 : m->edge_rise - m->edge_prev_rise;
        m->from_edges++;
        push(e, m, (mcu_pulse){ m->edge_rise, now - m->edge_rise, period });
    }
}

/* a motor: on timer `timer` channel 0..2 (its pin's edges while the compare output is disconnected), or
 * (timer -1) on the pin's edges; false when there is no room */
MCU_API bool mcu_motor_add(mcu_engine *e, int8_t timer, uint8_t channel, char port, uint8_t bit, uint16_t ddr)
{
    if (e->n_motors == MCU_MOTORS)
        return false;
    mcu_motor *m = &e->motors[e->n_motors];
    *m = (mcu_motor){ .engine = e,
                      .timer = timer,
                      .channel = channel,
                      .port = (uint8_t)port,
                      .bit = bit,
                      .ddr = ddr,
                      .edge_rise = MCU_NEVER,
                      .edge_prev_rise = MCU_NEVER };
    avr_irq_t *irq = avr_io_getirq(e->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
    if (!irq)
        return false;
    avr_irq_register_notify(irq, pin_changed, m);
    e->n_motors++;
    return true;
}

/* how many of the motor's pulses came from the timer's registers (0) or from its pin's edges (1) */
MCU_API uint32_t mcu_motor_source(const mcu_engine *e, uint8_t motor, int edges)
{
    const mcu_motor *m = &e->motors[motor];
    return edges ? m->from_edges : m->from_timer;
}

uint64_t mcu_pwm_next(const mcu_engine *e)
{
    uint64_t next = MCU_NEVER;
    for (int i = 0; i < 6; i++)
        if (e->timers[i].used && e->timers[i].next < next)
            next = e->timers[i].next;
    return next;
}

void mcu_pwm_event(mcu_engine *e)
{
    for (int i = 0; i < 6; i++) {
        mcu_timer *tm = &e->timers[i];
        while (tm->used && tm->next <= e->avr->cycle)
            step(e, tm);
    }
}

/* after a reset: the registers are cleared, so is every timer */
void mcu_pwm_reset(mcu_engine *e)
{
    for (int i = 0; i < 6; i++)
        if (e->timers[i].used)
            reconfigure(e, &e->timers[i]);
    for (int i = 0; i < e->n_motors; i++)
        e->motors[i].edge_rise = e->motors[i].edge_prev_rise = MCU_NEVER;
}

/* the motor's pulses ended since the last take: (rise, width, period) in ns, three per pulse */
MCU_API uint32_t mcu_pulses(mcu_engine *e, uint8_t motor, uint64_t *out, uint32_t max)
{
    mcu_motor *m = &e->motors[motor];
    flush(e, m, e->avr->cycle, false);
    uint32_t n = m->n_out < max ? m->n_out : max;
    for (uint32_t i = 0; i < n; i++) {
        mcu_pulse p = m->out[i];
        uint64_t rise = mcu_ns(e, p.rise);
        out[3 * i] = rise;
        out[3 * i + 1] = mcu_ns(e, p.rise + p.width) - rise;
        out[3 * i + 2] = mcu_ns(e, p.rise + p.period) - rise;
    }
    memmove(m->out, m->out + n, (m->n_out - n) * sizeof m->out[0]);
    m->n_out = (uint16_t)(m->n_out - n);
    return n;
}

/* every motor's pulses in one call (the session takes them each plant tick): counts[i] pulses of
   motor i, one after the other in out, max in all; returns how many in all (max: call again) */
MCU_API uint32_t mcu_pulses_all(mcu_engine *e, uint64_t *out, uint32_t max, uint32_t *counts)
{
    uint32_t total = 0;
    for (uint8_t i = 0; i < e->n_motors; i++) {
        counts[i] = mcu_pulses(e, i, out + 3 * total, max - total);
        total += counts[i];
    }
    return total;
}
