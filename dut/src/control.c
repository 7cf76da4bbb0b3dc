/* Control: seed 000's position-form PID (eq. 8) used for the angle, rate, altitude and vertical
   acceleration loops (eqs. 9-12), the limits (eqs. 13-14), the mixers (eq. 15 and X), the throttle
   compensation (eq. 16), barometric altitude (eq. 6) and its fusion with vertical acceleration. */
#include <math.h>

#include "fc.h"

real clampd(real v, real lo, real hi) { return v < lo ? lo : v > hi ? hi : v; }

void pid_init(pid *p, real kp, real ki, real kd, real out_limit, real sum_limit)
{
    *p = (pid){ .kp = kp, .ki = ki, .kd = kd, .out_limit = out_limit, .sum_limit = sum_limit };
}

void pid_reset(pid *p)
{
    p->sum = p->prev = 0;
    p->started = 0;
}

real pid_step(pid *p, real e, real T)
{
    if (!(p->i_band > 0) || fabs(e) <= p->i_band)
        p->sum += e * T;
    if (p->sum_limit > 0 && p->ki != 0) {
        real lim = p->sum_limit / fabs(p->ki);
        p->sum = clampd(p->sum, -lim, lim);
    }
    real d = p->started ? (e - p->prev) / T : 0.0; /* no derivative kick on the first step */
    p->prev = e;
    p->started = 1;
    real u = p->kp * e + p->ki * p->sum + p->kd * d;
    return p->out_limit > 0 ? clampd(u, -p->out_limit, p->out_limit) : u;
}

void mix(enum mixer_kind kind, real throttle, real roll, real pitch, real yaw, real out[4])
{
    if (kind == MIXER_PLUS) { /* eq. 15: 1 front, 2 left, 3 rear, 4 right; 1 and 3 counter-clockwise */
        out[0] = throttle + pitch + yaw;
        out[1] = throttle + roll - yaw;
        out[2] = throttle - pitch + yaw;
        out[3] = throttle - roll - yaw;
    } else { /* X: the '+' layout turned 45 deg clockwise seen from above, as the plant's frame = 1:
                1 front-right, 2 front-left, 3 rear-left, 4 rear-right; 1 and 3 counter-clockwise */
        out[0] = throttle - roll + pitch + yaw;
        out[1] = throttle + roll + pitch - yaw;
        out[2] = throttle + roll - pitch + yaw;
        out[3] = throttle - roll - pitch - yaw;
    }
}

real throttle_compensate(real value, real alpha, real beta) { return alpha * (value - beta); }

real baro_altitude(real pressure, real start_pressure)
{
    return 44330.0 * (1.0 - pow(pressure / start_pressure, 0.1903));
}

void alt_filter_init(alt_filter *a, real k1, real k2) { *a = (alt_filter){ .k1 = k1, .k2 = k2 }; }

void alt_filter_update(alt_filter *a, real baro_h, real acc_up, real T)
{
    if (!a->started) {
        a->h = baro_h;
        a->v = 0;
        a->started = 1;
        return;
    }
    real err = baro_h - a->h;
    a->v += (acc_up + a->k2 * err) * T;
    a->h += (a->v + a->k1 * err) * T;
}
