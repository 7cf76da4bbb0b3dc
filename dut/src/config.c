/* The configuration's defaults and gain profiles, for both platforms (no stdio: the AVR links this). */
#include "config.h"

#include <string.h>

#include "config_keys.h"

/* Gain profiles: "default" is tuned on the rig's plant (seed 001 vehicle); "seed002" is the nested
   PI-PID of seed 002 (Table 2 outer PI 4.5/0.35, Table 3 inner PID 0.14/0.015/0.0025 in units of the
   throttle range per rad/s, here x1000 us). Keys after "profile" in a file override it. */
int config_profile(fc_config *c, int index)
{
    if (index == 0) {
        c->angle_kp = 4.5;
        c->angle_ki = 0.35;
        c->angle_kd = 0;
        c->rate_kp = 40;
        c->rate_ki = 40;
        c->rate_kd = 0.5;
    } else if (index == 1) {
        c->angle_kp = 4.5;
        c->angle_ki = 0.35;
        c->angle_kd = 0;
        c->rate_kp = 140;
        c->rate_ki = 15;
        c->rate_kd = 2.5;
    } else {
        return -1;
    }
    return 0;
}

int config_profile_index(const char *name)
{
#define PROFILE(p) #p,
    static const char *const names[] = { FC_PROFILES(PROFILE) };
#undef PROFILE
    for (int i = 0; i < (int)(sizeof names / sizeof names[0]); i++)
        if (strcmp(name, names[i]) == 0)
            return i;
    return -1;
}

void config_defaults(fc_config *c)
{
    memset(c, 0, sizeof *c);
    strcpy(c->i2c_path, "/dev/i2c-1");
    c->mpu_addr = 0x68;
    c->hmc_addr = 0x1E;
    c->baro_addr = 0x77;
    c->est_rate_hz = 250;
    c->ctrl_rate_hz = 250;
    c->gyro_fault_check = 1;
    c->kp_est = 0.3;
    c->ki_est = 0.01;
    config_profile(c, 0);
    c->yaw_rate_kp = 300;
    c->yaw_rate_ki = 30;
    c->alt_kp = 2.0;
    c->alt_ki = 0.03;
    c->alt_kd = 0.0;
    c->alt_kv = 3.0;
    c->alt_i_band_m = 0.3;
    c->baro_gate_m = 3.0;
    c->alt_sp_range_m = 5.0;
    c->acc_kp = 2.0;
    c->acc_ki = 0.5;
    c->acc_kd = 0.0;
    c->angle_limit = 100;
    c->alt_limit = 10;
    c->hover_us = 1511;
    c->max_angle_deg = 30;
    c->max_yaw_rate_dps = 90;
    for (int i = 0; i < 4; i++) {
        c->alpha[i] = 1;
        c->beta[i] = 0;
    }
    for (int i = 0; i < 3; i++) {
        c->acc_scale[i] = 1;
        c->mag_scale[i] = 1;
    }
    c->telemetry_every = 5;
    c->arm_hold_s = 1.0;
}

int config_check(const fc_config *c) { return c->ctrl_rate_hz > c->est_rate_hz ? -1 : 0; }
