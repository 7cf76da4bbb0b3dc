/* The reference FC's configuration: one struct for both platforms. The keys are one table
   (config_keys.h); Linux reads them from a "key = value" file (dut/linux/config_file.c), the AVR from an
   EEPROM image (config_image.c); the defaults and the gain profiles are here, in config.c. */
#ifndef CONFIG_H
#define CONFIG_H

#include "fc.h"

typedef struct {
    char i2c_path[64];
    int mpu_addr, hmc_addr, baro_addr;
    char rc_path[64];        /* empty: no RC, stays disarmed */
    char telemetry_path[64]; /* empty: no telemetry */
    int pwm_chip;
    int estimator;     /* 0 quaternion CF (seed 000), 1 Mahony DCM (seed 002), 2 EKF */
    int mixer;         /* 0 '+', 1 X */
    real est_rate_hz;  /* sensor reads and attitude estimation (the loop rate) */
    real ctrl_rate_hz; /* control and motor output, at most est_rate_hz */
    /* negative controls for the rig's own tests: a firmware with a defect the rig must catch */
    int defect_mixer_sign; /* 1: roll command sign inverted in the mixer */
    int defect_never_arm;  /* 1: ignores the arm switch */
    int gyro_fault_check;  /* 1 (default): a gyro that repeats one sample is detected and replaced */
    real defect_crash_at;  /* > 0: abort() at this many seconds after start */
    real kp_est, ki_est;
    real angle_kp, angle_ki, angle_kd; /* eq. 9 */
    real rate_kp, rate_ki, rate_kd;    /* eq. 10 */
    real yaw_rate_kp, yaw_rate_ki;
    real alt_kp, alt_ki, alt_kd; /* eq. 11 */
    real baro_gate_m;            /* barometer innovation gate */
    real alt_kv;                 /* damping: m/s^2 per m/s of the fused climb rate */
    real alt_i_band_m;           /* the altitude integral runs only this close to the setpoint (0: always) */
    real alt_sp_range_m;         /* alt hold: RC ch7 at full deflection moves the setpoint this far */
    real acc_kp, acc_ki, acc_kd; /* eq. 12 */
    real angle_limit, alt_limit; /* eqs. 13-14 */
    real hover_us;
    real max_angle_deg, max_yaw_rate_dps;
    real alpha[4], beta[4]; /* eq. 16 */
    real acc_offset[3], acc_scale[3], mag_offset[3], mag_scale[3];
    int telemetry_every;
    int telemetry_proto; /* FC_TEL_*: what the telemetry port speaks */
    int arming;          /* FC_ARM_*: how the pilot arms */
    real arm_hold_s;     /* FC_ARM_STICKS: how long the gesture is held */
    int sbus_map;        /* FC_SBUS_*: how SBUS values become stick positions */
} fc_config;

/* telemetry_proto: text lines (dut/linux/main.c, dut/avr/telemetry.c); MSP v1, answering requests;
   MAVLink v2, streaming (src/binary_telemetry.c) */
enum { FC_TEL_TEXT = 0, FC_TEL_MSP = 1, FC_TEL_MAVLINK = 2 };
/* arming: channel 5 high with throttle low; or MultiWii's gesture, throttle low and yaw right held
   arm_hold_s (throttle low and yaw left held disarms) */
enum { FC_ARM_SWITCH = 0, FC_ARM_STICKS = 1 };
/* sbus_map: the standard scale (172..1811 -> -1..1); or MultiWii 2.4's (raw / 2 + 988 us stretched x1.25
   about 1500 us, 1000..2000 us -> -1..1: a transmitter's 172..1811 reaches 968..1991 us) */
enum { FC_SBUS_STANDARD = 0, FC_SBUS_MULTIWII = 1 };

void config_defaults(fc_config *c);
/* The gain profiles, FC_PROFILES order (0 "default", 1 "seed002"): sets their gains; -1 when there is no
   such profile. */
int config_profile(fc_config *c, int index);
int config_profile_index(const char *name); /* -1: none of that name */
/* The rule that relates two keys: 0, or -1 when ctrl_rate_hz exceeds est_rate_hz. */
int config_check(const fc_config *c);
/* Reads "key = value" lines (Linux: dut/linux/config_file.c); returns 0, or -1 with a message naming the
   file, line and key. */
int config_load(fc_config *c, const char *path, char *err, int errlen);

#endif
