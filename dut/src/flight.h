/* One cycle of the reference FC's flight logic, for both platforms: calibration of the sensor samples,
   the estimator, the altitude fusion with its barometer gate, RC (arming, link loss, failsafe), the gyro
   fault ride-through, and the cascaded control to four pulse widths. The platform reads the chips, the
   RC bytes and its clock, and calls these in the order of one loop cycle:
     flight_sense  (the MPU-6050 sample; the HMC5883L's, when the platform read one)
     flight_baro   (a pressure from ms5611_poll, when there was one)
     flight_rc     (each valid SBUS frame)
     flight_control (returns whether this cycle wrote the motors, and what happened worth saying)
   Times are the platform's clock in seconds (double: on Linux seconds since boot). */
#ifndef FLIGHT_H
#define FLIGHT_H

#include "config.h"
#include "fc.h"

#define FLIGHT_RC_TIMEOUT_S 0.5
#define FLIGHT_FAILSAFE_DESCENT_S 10.0
#define FLIGHT_GYRO_STUCK_S 0.04 /* a gyro repeating one sample this long is stuck: 10 cycles at 250 Hz */

/* what flight_control reports (a bit set) */
enum {
    FLIGHT_CONTROLLED = 1, /* this cycle computed out[] */
    FLIGHT_GYRO_STUCK = 2, /* the gyro was declared stuck this cycle */
    FLIGHT_GYRO_RECOVERED = 4,
    FLIGHT_RC_LOST = 8, /* the RC link was lost while armed: failsafe began */
};

typedef struct {
    const fc_config *c;
    real T, Tc;
    vec3 bias, mag; /* gyro bias (body); the newest calibrated field (body) */
    quat_cf cf;
    mahony_dcm mh;
#ifndef FC_NO_EKF /* (the AVR leaves the EKF out: it does not fit the cycle budget, docs/avr-fc.md) */
    ekf7 kf;
#endif
    euler att;
    vec3 w, a; /* this cycle's body rates (bias removed) and calibrated specific force */
    real acc_up;
    pid angle[2], rate[3], alt_pid, acc_pid;
    alt_filter altf;
    sbus_frame sticks;
    double last_rc, failsafe_since, last_baro; /* clock seconds */
    real start_pressure, alt_target, alt_base;
    int baro_rejects, armed, had_rc, alt_hold, gyro_same, gyro_fault, rc_ok, events;
    int stuck_n;        /* FLIGHT_GYRO_STUCK_S in cycles (at least 3) */
    int all_estimators; /* flight_align: all three, or c->estimator's only */
    double ctrl_phase;
    vec3 last_gyro;
    real rate_sp[3], throttle; /* the outer loops' set points for the rate loop (rad/s) and throttle (us) */
    int inner_on;              /* armed, the gyro sound, set points computed: the rate loop runs */
    int gesture;               /* FC_ARM_STICKS: the stick gesture held (1 arm, -1 disarm, 0 none) */
    double gesture_since;      /* clock second it began */
    real out[4];
} flight;

/* Sensor frame of a board lying flat (x forward, y left, z up) to body FRD. */
vec3 flight_to_body(vec3 s);
vec3 flight_calibrate(vec3 v, const real off[3], const real scale[3]);

/* After the platform's second at rest: the gyro bias and the mean specific force and field (body,
   calibrated; a zero field when none was read). Sets up the filters (aligned to the resting vectors
   through themselves, at a high gain) and the loops. `all_estimators`: align all three (Linux), or
   only c->estimator's (the AVR, where the EKF is not built and time counts). The alignment runs 4 s of
   the filters' time in align_steps steps: 1000 on Linux (instant there); 100 on the AVR, where 1000
   updates took 1.4 s and the loop started after the scenarios' arming at 1.2 s. The field stays the
   newest until flight_sense gets another. */
/* flight_init in its parts, for a platform that aligns while it calibrates (the AVR: its filter
   updates take the time a calibration sample leaves, so the loop starts when Linux's does): flight_start;
   flight_align steps on the means so far (Ta: each step's filter time, 4 s in all); flight_ready */
void flight_start(flight *f, const fc_config *c, int all_estimators);
void flight_align(flight *f, vec3 acc_mean, vec3 mag_mean, real Ta);
void flight_ready(flight *f, vec3 bias, vec3 mag_mean);
void flight_init(flight *f, const fc_config *c, vec3 bias, vec3 acc_mean, vec3 mag_mean, int all_estimators,
                 int align_steps, void (*each)(void)); /* each: called between alignment steps (a watchdog), or NULL */
/* acc (m/s^2) and gyro (rad/s) in the sensor frame; mag (gauss, sensor frame) or NULL when none was read:
   flight_measure (the gyro check, calibration) then flight_estimate (the estimator, vertical acceleration).
   A platform whose estimator takes a large part of the cycle (the AVR: 3.4 of 10 ms) runs the control
   between the two, so the rate loop acts on a fresh gyro sample at once and the attitude loop on the
   previous cycle's estimate (the delay from sample to motors is the rate loop's margin). */
void flight_sense(flight *f, vec3 acc, vec3 gyro, const vec3 *mag);
void flight_measure(flight *f, vec3 acc, vec3 gyro, const vec3 *mag);
void flight_estimate(flight *f);
void flight_baro(flight *f, int32_t p_pa, double t0);
void flight_rc(flight *f, const sbus_frame *frame, double t0);
int flight_control(flight *f, double t0);
/* flight_control in its two halves, for a platform whose rate loop runs faster than its estimator (the
   AVR): flight_outer (RC, arming, failsafe, the attitude and altitude loops: the rate set points and the
   throttle, at ctrl_rate_hz) and flight_inner (the rate PIDs on the newest f->w, the mixer, out[]; dt its
   own period; returns whether it wrote out[]). flight_control is flight_outer then, on a control cycle,
   flight_inner with dt = 1 / ctrl_rate_hz: the same arithmetic as before the split. */
int flight_outer(flight *f, double t0);
int flight_inner(flight *f, real dt);

#endif
