/* The canned motion the estimator benches feed (bench/fc_bench.c on the host, bench/avr_fc_cycles.c on
   the AVR under simavr): one definition, so the two platforms' figures are of the same inputs. */
#ifndef CANNED_MOTION_H
#define CANNED_MOTION_H

#include <math.h>

#include "fc.h"

/* Sample k of a recorded-style motion at 250 Hz: a slow roll/pitch wobble, a constant yaw rate, and a
   field turning slowly in the horizontal plane. */
static inline void canned_motion(long k, vec3 *gyro, vec3 *acc, vec3 *mag)
{
    real t = k * 0.004;
    *gyro = v3(0.2 * sin(t), 0.1 * cos(0.7 * t), 0.05);
    *acc = v3(0.3 * sin(t), -0.2 * cos(t), -9.7);
    *mag = v3(0.25 * cos(0.05 * t), 0.25 * sin(0.05 * t), 0.433);
}

#endif
