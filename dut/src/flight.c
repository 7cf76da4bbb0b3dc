/* The reference FC's flight logic, one cycle at a time (flight.h), moved here from the Linux program
   unchanged so that the AVR firmware flies the very same code: the platforms only read chips and clocks.
   A gyro that repeats one sample for FLIGHT_GYRO_STUCK_S (in cycles of the loop: 10 at 250 Hz, 5 on the
   AVR's slower loop, so the fault is caught as soon at any rate) while armed is declared failed: without
   rate feedback the loops would wind up, so the FC holds zero differential torque at descent throttle
   until the gyro moves again (fault ride-through; defect negative control: gyro_fault_check = 0). */
#include "flight.h"

#include <string.h>

vec3 flight_to_body(vec3 s) { return v3(s.x, -s.y, -s.z); }

vec3 flight_calibrate(vec3 v, const real off[3], const real scale[3])
{
    return v3((v.x - off[0]) * scale[0], (v.y - off[1]) * scale[1], (v.z - off[2]) * scale[2]);
}

static real i_limit(real out_limit, real ki) { return ki > 0 ? 0.5 * out_limit / ki : 0; }

void flight_start(flight *f, const fc_config *c, int all_estimators)
{
    memset(f, 0, sizeof *f);
    f->c = c;
    f->all_estimators = all_estimators;
    f->T = 1.0 / c->est_rate_hz;
    f->Tc = 1.0 / c->ctrl_rate_hz;
    quat_cf_init(&f->cf, c->kp_est, c->ki_est);
    mahony_init(&f->mh, c->kp_est, c->ki_est);
#ifndef FC_NO_EKF
    ekf_init(&f->kf);
#endif
    /* initial alignment: the resting accelerometer and magnetometer (means), through the filters themselves
       with a high gain, so a vehicle that starts tilted (the seed 000 roll stand) starts estimated */
    f->cf.kp = f->mh.kp = 5.0;
    f->cf.ki = f->mh.ki = 0.0;
}

void flight_align(flight *f, vec3 acc_mean, vec3 mag, real Ta)
{
    const fc_config *c = f->c;
    if (f->all_estimators || c->estimator == 0)
        quat_cf_update(&f->cf, v3(0, 0, 0), acc_mean, mag, Ta);
    if (f->all_estimators || c->estimator == 1)
        mahony_update(&f->mh, v3(0, 0, 0), acc_mean, mag, Ta);
#ifndef FC_NO_EKF
    if (f->all_estimators || c->estimator == 2)
        ekf_update(&f->kf, v3(0, 0, 0), acc_mean, mag, Ta);
#endif
}

void flight_init(flight *f, const fc_config *c, vec3 bias, vec3 acc_mean, vec3 mag, int all_estimators, int align_steps,
                 void (*each)(void))
{
    flight_start(f, c, all_estimators);
    const real Ta = 4.0 / align_steps; /* 4 s of the filters' time, 20 time constants at kp 5 */
    for (int i = 0; i < align_steps; i++) {
        flight_align(f, acc_mean, mag, Ta);
        if (each)
            each();
    }
    flight_ready(f, bias, mag);
}

void flight_ready(flight *f, vec3 bias, vec3 mag)
{
    const fc_config *c = f->c;
    f->bias = bias;
    f->mag = mag;
    f->cf.kp = f->mh.kp = c->kp_est;
    f->cf.ki = f->mh.ki = c->ki_est;
    f->cf.integral = f->mh.integral = v3(0, 0, 0);
    for (int i = 0; i < 2; i++) {
        pid_init(&f->angle[i], c->angle_kp, c->angle_ki, c->angle_kd, 0,
                 0.1); /* anti-windup: I adds <= ki * 0.1 rad/s */
        /* anti-windup: the integral term may supply at most half the output limit, so a large
           manoeuvre (the roll stand's release) does not leave a slowly unwinding tail */
        pid_init(&f->rate[i], c->rate_kp, c->rate_ki, c->rate_kd, c->angle_limit, i_limit(c->angle_limit, c->rate_ki));
    }
    pid_init(&f->rate[2], c->yaw_rate_kp, c->yaw_rate_ki, 0, c->angle_limit, i_limit(c->angle_limit, c->yaw_rate_ki));
    /* the altitude loop asks for at most 3 m/s^2, its integral for at most 0.5: engaging hold while
       climbing fast must not wind up a slow oscillation */
    pid_init(&f->alt_pid, c->alt_kp, c->alt_ki, c->alt_kd, 3.0, 0.5);
    /* and it integrates only within alt_i_band_m of the setpoint: hold engaged while climbing carries
       the vehicle a metre past the setpoint, and integrating that excursion left a wound-up term
       that took ten seconds to unwind (a slow creep, the 1 m step's steady-state error) */
    f->alt_pid.i_band = c->alt_i_band_m;
    pid_init(&f->acc_pid, c->acc_kp, c->acc_ki, c->acc_kd, c->alt_limit, c->alt_limit / 2);
    alt_filter_init(&f->altf, 2.0, 1.0);
    f->last_rc = -1e9;
    f->failsafe_since = -1;
    f->ctrl_phase = 1.0; /* the first cycle controls */
    f->stuck_n = (int)(FLIGHT_GYRO_STUCK_S * c->est_rate_hz + 0.5);
    if (f->stuck_n < 3)
        f->stuck_n = 3;
    for (int i = 0; i < 4; i++)
        f->out[i] = 1000;
}

void flight_measure(flight *f, vec3 acc, vec3 gyro, const vec3 *mag)
{
    const fc_config *c = f->c;
    f->gyro_same =
        (gyro.x == f->last_gyro.x && gyro.y == f->last_gyro.y && gyro.z == f->last_gyro.z) ? f->gyro_same + 1 : 0;
    f->last_gyro = gyro;
    int stuck = f->armed && c->gyro_fault_check && f->gyro_same >= f->stuck_n;
    if (stuck != f->gyro_fault)
        f->events |= stuck ? FLIGHT_GYRO_STUCK : FLIGHT_GYRO_RECOVERED;
    f->gyro_fault = stuck;
    f->a = flight_calibrate(flight_to_body(acc), c->acc_offset, c->acc_scale);
    f->w = v3_add(flight_to_body(gyro), v3_scale(f->bias, -1));
    if (mag)
        f->mag = flight_calibrate(flight_to_body(*mag), c->mag_offset, c->mag_scale);
}

void flight_estimate(flight *f)
{
    const fc_config *c = f->c;
    if (c->estimator == 0) {
        quat_cf_update(&f->cf, f->w, f->a, f->mag, f->T);
        f->att = quat_to_euler(f->cf.q);
    } else if (c->estimator == 1) {
        mahony_update(&f->mh, f->w, f->a, f->mag, f->T);
        f->att = dcm_to_euler(f->mh.R);
    } else {
#ifndef FC_NO_EKF
        ekf_update(&f->kf, f->w, f->a, f->mag, f->T);
        f->att = ekf_euler(&f->kf);
#endif
    }
    /* vertical acceleration: specific force rotated to earth, plus gravity, up positive */
    real cr = cos(f->att.roll), sr = sin(f->att.roll), cpi = cos(f->att.pitch), spi = sin(f->att.pitch);
    f->acc_up = -(-spi * f->a.x + cpi * sr * f->a.y + cpi * cr * f->a.z + FC_G0);
}

void flight_sense(flight *f, vec3 acc, vec3 gyro, const vec3 *mag)
{
    flight_measure(f, acc, gyro, mag);
    flight_estimate(f);
}

void flight_baro(flight *f, int32_t p_pa, double t0)
{
    if (f->start_pressure == 0)
        f->start_pressure = p_pa;
    double dt = f->last_baro > 0 ? t0 - f->last_baro : 0.0; /* the first pair only initialises */
    f->last_baro = t0;
    /* innovation gate: a barometer jump of more than baro_gate_m against the fused altitude is a
       glitch, not a climb; after 25 rejections in a row (about 0.6 s) the reading is believed */
    real bh = baro_altitude(p_pa, f->start_pressure);
    alt_filter *altf = &f->altf;
    if (altf->started && fabs(bh - altf->h) > f->c->baro_gate_m && f->baro_rejects < 25) {
        f->baro_rejects++;
        alt_filter_update(altf, altf->h, f->acc_up, dt); /* coast on the accelerometer */
    } else {
        f->baro_rejects = 0;
        alt_filter_update(altf, bh, f->acc_up, dt);
    }
}

void flight_rc(flight *f, const sbus_frame *frame, double t0)
{
    if (frame->failsafe || frame->frame_lost)
        return; /* the receiver's own failsafe: as no frame at all */
    f->sticks = *frame;
    f->last_rc = t0;
    f->had_rc = 1;
}

/* A channel's stick position, -1..1, by the configured scale (config.h FC_SBUS_*) */
static real stick(const flight *f, int ch)
{
    uint16_t raw = f->sticks.ch[ch];
    return f->c->sbus_map == FC_SBUS_MULTIWII ? sbus_to_unit_multiwii(raw) : sbus_to_unit(raw);
}

/* MultiWii's arming gesture: throttle low and yaw right (its MINCHECK 1100 and MAXCHECK 1900 us: -0.8 and
   0.8 of the stick) held arm_hold_s arms; throttle low and yaw left held as long disarms */
static void arm_by_sticks(flight *f, double t0)
{
    real yaw = stick(f, 3);
    int gesture = stick(f, 2) >= -0.8 ? 0 : yaw > 0.8 ? 1 : yaw < -0.8 ? -1 : 0;
    if (gesture != f->gesture) {
        f->gesture = gesture;
        f->gesture_since = t0;
    }
    if (gesture == 0 || t0 - f->gesture_since < f->c->arm_hold_s)
        return;
    if (gesture > 0 && !f->c->defect_never_arm)
        f->armed = 1;
    if (gesture < 0)
        f->armed = 0;
}

int flight_outer(flight *f, double t0)
{
    const fc_config *c = f->c;
    int events = f->events;
    f->events = 0;
    int rc_ok = f->rc_ok = f->had_rc && t0 - f->last_rc < FLIGHT_RC_TIMEOUT_S;
    real thr = (stick(f, 2) + 1) / 2; /* 0..1 */
    if (rc_ok) {
        f->failsafe_since = -1;
        if (c->arming == FC_ARM_STICKS) {
            arm_by_sticks(f, t0);
        } else {
            int arm_switch = stick(f, 4) > 0.5;
            if (!f->armed && arm_switch && thr < 0.05 && !c->defect_never_arm)
                f->armed = 1;
            if (!arm_switch)
                f->armed = 0;
        }
        f->alt_hold = stick(f, 5) > 0.5;
    } else if (f->armed) {
        if (f->failsafe_since < 0) {
            f->failsafe_since = t0;
            events |= FLIGHT_RC_LOST;
            f->alt_target = f->altf.h;
        }
        f->alt_hold = 1;
        f->alt_target -= 0.5 * f->T; /* descend at 0.5 m/s */
        if (t0 - f->failsafe_since > FLIGHT_FAILSAFE_DESCENT_S)
            f->armed = 0;
    }
    f->ctrl_phase += c->ctrl_rate_hz / c->est_rate_hz;
    int control_now = f->ctrl_phase >= 1.0 - 1e-9;
    if (control_now)
        f->ctrl_phase -= 1.0;
    /* alt hold setpoint: the altitude where hold engaged, moved by RC ch7 (centre: no offset) */
    real alt_offset = rc_ok ? stick(f, 6) * c->alt_sp_range_m : 0;
    if (rc_ok && f->alt_hold)
        f->alt_target = f->alt_base + alt_offset;
    const alt_filter *altf = &f->altf;
    real *out = f->out;
    if (control_now && f->armed && f->gyro_fault) {
        f->inner_on = 0;
        for (int i = 0; i < 4; i++) /* zero differential torque, 5 % under hover: a slow descent */
            out[i] = clampd(c->hover_us - 0.05 * (c->hover_us - 1000), 1000, 2000);
        f->alt_target = altf->h;
        f->alt_base = altf->h - alt_offset; /* after recovery, hold where the descent ended */
    } else if (control_now && f->armed) {
        real sp_roll = rc_ok ? stick(f, 0) * c->max_angle_deg * M_PI / 180 : 0;
        real sp_pitch = rc_ok ? stick(f, 1) * c->max_angle_deg * M_PI / 180 : 0;
        /* (the arming gesture's yaw is not a yaw command: with the throttle low, as MultiWii, none) */
        int gesture_yaw = c->arming == FC_ARM_STICKS && f->gesture != 0;
        f->rate_sp[2] = rc_ok && !gesture_yaw ? stick(f, 3) * c->max_yaw_rate_dps * M_PI / 180 : 0;
        f->rate_sp[0] = pid_step(&f->angle[0], sp_roll - f->att.roll, f->Tc); /* eq. 9 */
        f->rate_sp[1] = pid_step(&f->angle[1], sp_pitch - f->att.pitch, f->Tc);
        if (f->alt_hold) { /* eqs. 11-12, limited (eq. 14), in percent of the throttle range */
            real acc_sp = pid_step(&f->alt_pid, f->alt_target - altf->h, f->Tc) - c->alt_kv * altf->v;
            f->throttle = c->hover_us - 1000 + 10 * pid_step(&f->acc_pid, acc_sp - f->acc_up, f->Tc);
        } else {
            f->throttle = thr * 1000;
            f->alt_target = altf->h;
            f->alt_base = altf->h - alt_offset; /* engaging hold keeps this altitude whatever ch7 says */
        }
        f->inner_on = 1;
    } else if (!f->armed) {
        f->inner_on = 0;
        for (int i = 0; i < 4; i++)
            out[i] = 1000;
        for (int i = 0; i < 2; i++) {
            pid_reset(&f->angle[i]);
            pid_reset(&f->rate[i]);
        }
        pid_reset(&f->rate[2]);
        pid_reset(&f->alt_pid);
        pid_reset(&f->acc_pid);
    }
    return events | (control_now ? FLIGHT_CONTROLLED : 0);
}

int flight_inner(flight *f, real dt)
{
    if (!f->inner_on || !f->armed || f->gyro_fault)
        return 0;
    const fc_config *c = f->c;
    real r_out = pid_step(&f->rate[0], f->rate_sp[0] - f->w.x, dt); /* eq. 10, limited (eq. 13) */
    real p_out = pid_step(&f->rate[1], f->rate_sp[1] - f->w.y, dt);
    real y_out = pid_step(&f->rate[2], f->rate_sp[2] - f->w.z, dt);
    if (c->defect_mixer_sign)
        r_out = -r_out; /* negative control: a roll sign error */
    real m[4];
    mix((enum mixer_kind)c->mixer, f->throttle, r_out, p_out, y_out, m);
    for (int i = 0; i < 4; i++)
        f->out[i] = clampd(1000 + throttle_compensate(m[i], c->alpha[i], c->beta[i]), 1000, 2000); /* eq. 16 */
    return 1;
}

int flight_control(flight *f, double t0)
{
    int events = flight_outer(f, t0);
    if (events & FLIGHT_CONTROLLED)
        flight_inner(f, f->Tc);
    return events;
}
