/* fc: the reference flight controller. Usage: fc [config-file]
   Start-up: sensors (fail: message, exit 2, no motor output), gyro bias from 500 samples at rest,
   motors at idle; then a loop at est_rate_hz on absolute deadlines: read sensors, estimate, read RC;
   at ctrl_rate_hz (a phase accumulator picks the cycles) control, mix, write PWM; emit telemetry.
   A gyro that repeats one sample for GYRO_STUCK_N cycles while armed is declared failed: without rate
   feedback the loops would wind up, so the FC holds zero differential torque at descent throttle until
   the gyro moves again (fault ride-through; defect negative control: gyro_fault_check = 0). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "config.h"
#include "drivers.h"

#define RC_TIMEOUT_S 0.5
#define FAILSAFE_DESCENT_S 10.0
#define GYRO_STUCK_N 10

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Sensor frame of a board lying flat (x forward, y left, z up) to body FRD. */
static vec3 to_body(vec3 s) { return v3(s.x, -s.y, -s.z); }

static void ts_add(struct timespec *t, long ns)
{
    t->tv_nsec += ns;
    while (t->tv_nsec >= 1000000000L) {
        t->tv_nsec -= 1000000000L;
        t->tv_sec++;
    }
}

static vec3 calibrate(vec3 v, const real off[3], const real scale[3])
{
    return v3((v.x - off[0]) * scale[0], (v.y - off[1]) * scale[1], (v.z - off[2]) * scale[2]);
}

static real i_limit(real out_limit, real ki) { return ki > 0 ? 0.5 * out_limit / ki : 0; }

int main(int argc, char **argv)
{
    fc_config c;
    char err[256];
    config_defaults(&c);
    if (argc > 2 || (argc == 2 && config_load(&c, argv[1], err, sizeof err) < 0)) {
        fprintf(stderr, "fc: %s\n", argc > 2 ? "usage: fc [config-file]" : err);
        return 2;
    }
    int bus = i2c_open(c.i2c_path);
    if (bus < 0) {
        fprintf(stderr, "fc: cannot open %s: %s\n", c.i2c_path, strerror(errno));
        return 2;
    }
    ms5611_dev baro;
    i2c_target baro_at = { bus, c.baro_addr };
    ms5611_bus baro_bus = ms5611_on_i2c(&baro_at);
    if (mpu_init(bus, c.mpu_addr, err, sizeof err) < 0 || hmc_init(bus, c.hmc_addr, err, sizeof err) < 0 ||
        ms5611_init(bus, c.baro_addr, &baro, err, sizeof err) < 0) {
        fprintf(stderr, "fc: %s; no motor output\n", err);
        return 2;
    }
    FILE *tel = NULL;
    if (c.telemetry_path[0] && !(tel = fopen(c.telemetry_path, "w"))) {
        fprintf(stderr, "fc: cannot open telemetry %s: %s\n", c.telemetry_path, strerror(errno));
        return 2;
    }
    int rc = -1;
    if (c.rc_path[0] && (rc = open(c.rc_path, O_RDONLY | O_NONBLOCK | O_NOCTTY)) < 0) {
        fprintf(stderr, "fc: cannot open RC input %s: %s\n", c.rc_path, strerror(errno));
        return 2;
    }
    const real T = 1.0 / c.est_rate_hz, Tc = 1.0 / c.ctrl_rate_hz;
    const double t_start = now_s();
    struct timespec next;
    long step_ns = (long)(1e9 / c.est_rate_hz);

    /* gyro bias: 500 samples at rest (seed 000); the field for the initial heading is averaged over the
       same second (one sample in 7, about the HMC5883L's 75 Hz): a single noisy sample started the
       heading a degree or two off, and the heading loop is slow to take that out */
    vec3 bias = v3(0, 0, 0), acc, gyro, mag = v3(0, 0, 0), acc_mean = v3(0, 0, 0), mag_sum = v3(0, 0, 0);
    int mag_n = 0;
    /* on absolute deadlines 2 ms apart: the second lasts a second however long the bus takes (on a bench
       each read costs real time; a relative sleep after it made calibration last 1.3 s there) */
    struct timespec cal;
    clock_gettime(CLOCK_MONOTONIC, &cal);
    for (int i = 0; i < 500; i++) {
        if (mpu_read(bus, c.mpu_addr, &acc, &gyro) < 0) {
            fprintf(stderr, "fc: MPU-6050 read failed during calibration; no motor output\n");
            return 2;
        }
        bias = v3_add(bias, v3_scale(to_body(gyro), 1.0 / 500));
        acc_mean = v3_add(acc_mean, v3_scale(calibrate(to_body(acc), c.acc_offset, c.acc_scale), 1.0 / 500));
        vec3 m;
        if (i % 7 == 0 && hmc_read(bus, c.hmc_addr, &m) == 0) {
            mag_sum = v3_add(mag_sum, calibrate(to_body(m), c.mag_offset, c.mag_scale));
            mag_n++;
        }
        ts_add(&cal, 2000000L);
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &cal, NULL);
    }
    if (pwm_setup(c.pwm_chip, 4, 2500000, err, sizeof err) < 0) {
        fprintf(stderr, "fc: %s\n", err);
        return 2;
    }
    quat_cf cf;
    mahony_dcm mh;
    ekf7 kf;
    quat_cf_init(&cf, c.kp_est, c.ki_est);
    mahony_init(&mh, c.kp_est, c.ki_est);
    ekf_init(&kf);
    { /* initial alignment: the resting accelerometer and magnetometer (means), through the filters themselves
         with a high gain, so a vehicle that starts tilted (the seed 000 roll stand) starts estimated */
        if (mag_n > 0)
            mag = v3_scale(mag_sum, 1.0 / mag_n);
        cf.kp = mh.kp = 5.0;
        cf.ki = mh.ki = 0.0;
        for (int i = 0; i < 1000; i++) {
            quat_cf_update(&cf, v3(0, 0, 0), acc_mean, mag, 0.004);
            mahony_update(&mh, v3(0, 0, 0), acc_mean, mag, 0.004);
            ekf_update(&kf, v3(0, 0, 0), acc_mean, mag, 0.004);
        }
        cf.kp = mh.kp = c.kp_est;
        cf.ki = mh.ki = c.ki_est;
        cf.integral = mh.integral = v3(0, 0, 0);
    }
    pid angle[2], rate[3], alt_pid, acc_pid;
    for (int i = 0; i < 2; i++) {
        pid_init(&angle[i], c.angle_kp, c.angle_ki, c.angle_kd, 0, 0.1); /* anti-windup: I adds <= ki * 0.1 rad/s */
        /* anti-windup: the integral term may supply at most half the output limit, so a large
           manoeuvre (the roll stand's release) does not leave a slowly unwinding tail */
        pid_init(&rate[i], c.rate_kp, c.rate_ki, c.rate_kd, c.angle_limit, i_limit(c.angle_limit, c.rate_ki));
    }
    pid_init(&rate[2], c.yaw_rate_kp, c.yaw_rate_ki, 0, c.angle_limit, i_limit(c.angle_limit, c.yaw_rate_ki));
    /* the altitude loop asks for at most 3 m/s^2, its integral for at most 0.5: engaging hold while
       climbing fast must not wind up a slow oscillation */
    pid_init(&alt_pid, c.alt_kp, c.alt_ki, c.alt_kd, 3.0, 0.5);
    /* and it integrates only within alt_i_band_m of the setpoint: hold engaged while climbing carries
       the vehicle a metre past the setpoint, and integrating that excursion left a wound-up term
       that took ten seconds to unwind (a slow creep, the 1 m step's steady-state error) */
    alt_pid.i_band = c.alt_i_band_m;
    pid_init(&acc_pid, c.acc_kp, c.acc_ki, c.acc_kd, c.alt_limit, c.alt_limit / 2);
    alt_filter altf;
    alt_filter_init(&altf, 2.0, 1.0);
    sbus_parser sp;
    sbus_parser_init(&sp);
    sbus_frame sticks;
    memset(&sticks, 0, sizeof sticks);
    double last_rc = -1e9, failsafe_since = -1, last_baro = 0; /* clock seconds */
    real start_pressure = 0, alt_target = 0, alt_base = 0;
    int baro_rejects = 0, armed = 0, had_rc = 0, reported_garbage = 0, alt_hold = 0, gyro_same = 0, gyro_fault = 0;
    double ctrl_phase = 1.0; /* the first cycle controls */
    vec3 last_gyro = v3(0, 0, 0);
    real out[4] = { 1000, 1000, 1000, 1000 };
    unsigned long cycles = 0, overruns = 0;
    double loop_max_us = 0;
    euler att = { 0, 0, 0 };

    /* the loop's deadlines start now: taken before the 1 s calibration, they made the first 250 cycles
       run back to back (counted as overruns) to catch up */
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (;;) {
        double t0 = now_s();
        if (mpu_read(bus, c.mpu_addr, &acc, &gyro) < 0) {
            fprintf(stderr, "fc: MPU-6050 read failed at t=%.3f; motors to idle and stop\n", t0);
            break;
        }
        if (c.defect_crash_at > 0 && t0 - t_start >= c.defect_crash_at)
            abort(); /* negative control: a firmware that crashes mid-flight */
        gyro_same = (gyro.x == last_gyro.x && gyro.y == last_gyro.y && gyro.z == last_gyro.z) ? gyro_same + 1 : 0;
        last_gyro = gyro;
        int stuck = armed && c.gyro_fault_check && gyro_same >= GYRO_STUCK_N;
        if (stuck != gyro_fault)
            fprintf(stderr, "fc: gyro %s at t=%.3f\n", stuck ? "stuck: holding level torque, descending" : "recovered",
                    t0);
        gyro_fault = stuck;
        vec3 a = calibrate(to_body(acc), c.acc_offset, c.acc_scale);
        vec3 w = v3_add(to_body(gyro), v3_scale(bias, -1));
        if (cycles % 4 == 0) { /* the HMC5883L updates at 75 Hz */
            vec3 m;
            if (hmc_read(bus, c.hmc_addr, &m) == 0)
                mag = calibrate(to_body(m), c.mag_offset, c.mag_scale);
        }
        if (c.estimator == 0) {
            quat_cf_update(&cf, w, a, mag, T);
            att = quat_to_euler(cf.q);
        } else if (c.estimator == 1) {
            mahony_update(&mh, w, a, mag, T);
            att = dcm_to_euler(mh.R);
        } else {
            ekf_update(&kf, w, a, mag, T);
            att = ekf_euler(&kf);
        }
        /* vertical acceleration: specific force rotated to earth, plus gravity, up positive */
        real cr = cos(att.roll), sr = sin(att.roll), cpi = cos(att.pitch), spi = sin(att.pitch);
        real acc_up = -(-spi * a.x + cpi * sr * a.y + cpi * cr * a.z + FC_G0);
        int32_t p_pa, t_c;
        if (ms5611_poll(&baro, &baro_bus, &p_pa, &t_c) == 1) {
            if (start_pressure == 0)
                start_pressure = p_pa;
            double dt = last_baro > 0 ? t0 - last_baro : 0.0; /* the first pair only initialises */
            last_baro = t0;
            /* innovation gate: a barometer jump of more than baro_gate_m against the fused altitude is a
               glitch, not a climb; after 25 rejections in a row (about 0.6 s) the reading is believed */
            real bh = baro_altitude(p_pa, start_pressure);
            if (altf.started && fabs(bh - altf.h) > c.baro_gate_m && baro_rejects < 25) {
                baro_rejects++;
                alt_filter_update(&altf, altf.h, acc_up, dt); /* coast on the accelerometer */
            } else {
                baro_rejects = 0;
                alt_filter_update(&altf, bh, acc_up, dt);
            }
        }
        /* RC */
        if (rc >= 0) {
            uint8_t buf[256];
            ssize_t n;
            sbus_frame f;
            while ((n = read(rc, buf, sizeof buf)) > 0)
                if (sbus_feed(&sp, buf, (size_t)n, &f) && !f.failsafe && !f.frame_lost) {
                    sticks = f;
                    last_rc = t0;
                    had_rc = 1;
                }
            if (sp.errors > 0 && !reported_garbage && sp.frames == 0 && sp.errors > 2 * SBUS_FRAME) {
                fprintf(stderr, "fc: RC input %s: %lu bytes that are not SBUS frames; staying disarmed\n", c.rc_path,
                        sp.errors);
                reported_garbage = 1;
            }
        }
        int rc_ok = had_rc && t0 - last_rc < RC_TIMEOUT_S;
        real thr = (sbus_to_unit(sticks.ch[2]) + 1) / 2; /* 0..1 */
        if (rc_ok) {
            failsafe_since = -1;
            int arm_switch = sbus_to_unit(sticks.ch[4]) > 0.5;
            if (!armed && arm_switch && thr < 0.05 && !c.defect_never_arm)
                armed = 1;
            if (!arm_switch)
                armed = 0;
            alt_hold = sbus_to_unit(sticks.ch[5]) > 0.5;
        } else if (armed) {
            if (failsafe_since < 0) {
                failsafe_since = t0;
                fprintf(stderr, "fc: RC lost at t=%.3f: failsafe (level, descend, disarm)\n", t0);
                alt_target = altf.h;
            }
            alt_hold = 1;
            alt_target -= 0.5 * T; /* descend at 0.5 m/s */
            if (t0 - failsafe_since > FAILSAFE_DESCENT_S)
                armed = 0;
        }
        ctrl_phase += c.ctrl_rate_hz / c.est_rate_hz;
        int control_now = ctrl_phase >= 1.0 - 1e-9;
        if (control_now)
            ctrl_phase -= 1.0;
        /* alt hold setpoint: the altitude where hold engaged, moved by RC ch7 (centre: no offset) */
        real alt_offset = rc_ok ? sbus_to_unit(sticks.ch[6]) * c.alt_sp_range_m : 0;
        if (rc_ok && alt_hold)
            alt_target = alt_base + alt_offset;
        if (control_now && armed && gyro_fault) {
            for (int i = 0; i < 4; i++) /* zero differential torque, 5 % under hover: a slow descent */
                out[i] = clampd(c.hover_us - 0.05 * (c.hover_us - 1000), 1000, 2000);
            alt_target = altf.h;
            alt_base = altf.h - alt_offset; /* after recovery, hold where the descent ended */
        } else if (control_now && armed) {
            real sp_roll = rc_ok ? sbus_to_unit(sticks.ch[0]) * c.max_angle_deg * M_PI / 180 : 0;
            real sp_pitch = rc_ok ? sbus_to_unit(sticks.ch[1]) * c.max_angle_deg * M_PI / 180 : 0;
            real sp_yaw_rate = rc_ok ? sbus_to_unit(sticks.ch[3]) * c.max_yaw_rate_dps * M_PI / 180 : 0;
            real r_sp = pid_step(&angle[0], sp_roll - att.roll, Tc); /* eq. 9 */
            real p_sp = pid_step(&angle[1], sp_pitch - att.pitch, Tc);
            real r_out = pid_step(&rate[0], r_sp - w.x, Tc); /* eq. 10, limited (eq. 13) */
            real p_out = pid_step(&rate[1], p_sp - w.y, Tc);
            real y_out = pid_step(&rate[2], sp_yaw_rate - w.z, Tc);
            if (c.defect_mixer_sign)
                r_out = -r_out; /* negative control: a roll sign error */
            real throttle;
            if (alt_hold) { /* eqs. 11-12, limited (eq. 14), in percent of the throttle range */
                real acc_sp = pid_step(&alt_pid, alt_target - altf.h, Tc) - c.alt_kv * altf.v;
                throttle = c.hover_us - 1000 + 10 * pid_step(&acc_pid, acc_sp - acc_up, Tc);
            } else {
                throttle = thr * 1000;
                alt_target = altf.h;
                alt_base = altf.h - alt_offset; /* engaging hold keeps this altitude whatever ch7 says */
            }
            real m[4];
            mix((enum mixer_kind)c.mixer, throttle, r_out, p_out, y_out, m);
            for (int i = 0; i < 4; i++)
                out[i] = clampd(1000 + throttle_compensate(m[i], c.alpha[i], c.beta[i]), 1000, 2000); /* eq. 16 */
        } else if (!armed) {
            for (int i = 0; i < 4; i++)
                out[i] = 1000;
            for (int i = 0; i < 2; i++) {
                pid_reset(&angle[i]);
                pid_reset(&rate[i]);
            }
            pid_reset(&rate[2]);
            pid_reset(&alt_pid);
            pid_reset(&acc_pid);
        }
        if (control_now)
            for (int i = 0; i < 4; i++)
                pwm_write_us(c.pwm_chip, i, out[i]);
        double loop_us = (now_s() - t0) * 1e6;
        loop_max_us = fmax(loop_max_us, loop_us);
        if (tel && cycles % (unsigned long)c.telemetry_every == 0) {
            fprintf(
                tel,
                "T t=%.4f roll=%.3f pitch=%.3f yaw=%.3f alt=%.3f armed=%d rc=%d gyro_fault=%d loop_us=%.0f max_us=%.0f "
                "overruns=%lu\n",
                t0, att.roll * 180 / M_PI, att.pitch * 180 / M_PI, att.yaw * 180 / M_PI, altf.h, armed, rc_ok,
                gyro_fault, loop_us, loop_max_us, overruns);
            fflush(tel);
        }
        cycles++;
        ts_add(&next, step_ns);
        struct timespec cur;
        clock_gettime(CLOCK_MONOTONIC, &cur);
        if (cur.tv_sec > next.tv_sec || (cur.tv_sec == next.tv_sec && cur.tv_nsec > next.tv_nsec))
            overruns++;
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
    }
    for (int i = 0; i < 4; i++)
        pwm_write_us(c.pwm_chip, i, 1000);
    return 3;
}
