/* ESC pulses from captured edges (docs/design.md §8): each channel's rising and falling edges, stamped
   with a capture timer's count that wraps (16 or 32 bits), become pulse widths in 0.1 us. A pulse is a
   glitch, counted and never reported, when it is shorter than min_width_us or longer than
   max_width_us, or when it starts less than min_period_us after the previous pulse's start; an edge
   that does not alternate with the one before (two rises, a fall with no rise) is counted as a glitch
   too. A channel with no good pulse for stale_us reports 0 (no pulse). The width of one pulse must fit
   in the counter (a 16-bit counter at 10 MHz: 6.5 ms, far above any ESC pulse); periods are measured
   on the microsecond clock, which does not wrap. Portable C99, no heap. */
#ifndef BRIDGE_PWM_CAPTURE_H
#define BRIDGE_PWM_CAPTURE_H

#include <stdint.h>

#define PWM_CAPTURE_CHANNELS 4

struct pwm_capture_cfg {
    uint8_t counter_bits;   /* 16 or 32 */
    uint32_t tick_hz;       /* the capture timer's count rate */
    uint32_t min_width_us;  /* shorter: a glitch (500) */
    uint32_t max_width_us;  /* longer: a glitch (2500) */
    uint32_t min_period_us; /* rising edges closer than this: a glitch (1000) */
    uint32_t stale_us;      /* no good pulse for this long: width 0 (100000) */
};

struct pwm_channel {
    int high;            /* the last edge was a rise */
    uint32_t rise_count; /* the counter at that rise */
    uint64_t rise_us;
    int have_pulse;
    uint64_t last_start_us; /* the last good pulse's rise */
    uint64_t good_us;       /* when the last good pulse ended */
    uint16_t width_tenth_us;
};

struct pwm_capture {
    struct pwm_capture_cfg cfg;
    struct pwm_channel ch[PWM_CAPTURE_CHANNELS];
    uint32_t pulses;   /* good pulses */
    uint32_t glitches; /* pulses or edges filtered out */
    uint64_t last_edge_us;
};

/* The defaults: 32-bit counter at 10 MHz, 500..2500 us, 1000 us minimum period, 100 ms stale. */
struct pwm_capture_cfg pwm_capture_defaults(void);
void pwm_capture_init(struct pwm_capture *pc, const struct pwm_capture_cfg *cfg);
/* An edge: level is the input after it (1 rising). Returns 1 when it ended a good pulse. Channels out
   of range are counted as glitches. */
int pwm_capture_edge(struct pwm_capture *pc, unsigned channel, int level, uint32_t count, uint64_t t_us);
/* The channels' widths now, in 0.1 us (0: no good pulse within stale_us). */
void pwm_capture_widths(const struct pwm_capture *pc, uint64_t now_us, uint16_t out[PWM_CAPTURE_CHANNELS]);

#endif
