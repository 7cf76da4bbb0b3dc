/* ESC pulses from captured edges: see pwm_capture.h. */
#include "pwm_capture.h"

#include <string.h>

struct pwm_capture_cfg pwm_capture_defaults(void)
{
    struct pwm_capture_cfg c = { 32, 10000000u, 500, 2500, 1000, 100000 };
    return c;
}

void pwm_capture_init(struct pwm_capture *pc, const struct pwm_capture_cfg *cfg)
{
    memset(pc, 0, sizeof *pc);
    pc->cfg = *cfg;
    if (pc->cfg.counter_bits != 16)
        pc->cfg.counter_bits = 32;
    if (!pc->cfg.tick_hz)
        pc->cfg.tick_hz = 1000000u;
}

static int glitch(struct pwm_capture *pc)
{
    pc->glitches++;
    return 0;
}

int pwm_capture_edge(struct pwm_capture *pc, unsigned channel, int level, uint32_t count, uint64_t t_us)
{
    if (channel >= PWM_CAPTURE_CHANNELS)
        return glitch(pc);
    pc->last_edge_us = t_us;
    struct pwm_channel *c = &pc->ch[channel];
    if (level) {
        int twice = c->high; /* a rise after a rise: the fall between was lost */
        c->high = 1;
        c->rise_count = count;
        c->rise_us = t_us;
        return twice ? glitch(pc) : 0;
    }
    if (!c->high) /* a fall with no rise before it */
        return glitch(pc);
    c->high = 0;
    uint32_t mask = pc->cfg.counter_bits == 16 ? 0xFFFFu : 0xFFFFFFFFu;
    uint32_t ticks = (count - c->rise_count) & mask; /* modulo the counter: a wrap in between is fine */
    uint64_t tenth = ((uint64_t)ticks * 10000000u + pc->cfg.tick_hz / 2) / pc->cfg.tick_hz;
    if (tenth < (uint64_t)pc->cfg.min_width_us * 10 || tenth > (uint64_t)pc->cfg.max_width_us * 10)
        return glitch(pc);
    if (c->have_pulse && c->rise_us - c->last_start_us < pc->cfg.min_period_us)
        return glitch(pc);
    c->have_pulse = 1;
    c->last_start_us = c->rise_us;
    c->good_us = t_us;
    c->width_tenth_us = (uint16_t)tenth;
    pc->pulses++;
    return 1;
}

void pwm_capture_widths(const struct pwm_capture *pc, uint64_t now_us, uint16_t out[PWM_CAPTURE_CHANNELS])
{
    for (int i = 0; i < PWM_CAPTURE_CHANNELS; i++) {
        const struct pwm_channel *c = &pc->ch[i];
        int fresh = c->have_pulse && now_us - c->good_us <= pc->cfg.stale_us;
        out[i] = fresh ? c->width_tenth_us : 0;
    }
}
