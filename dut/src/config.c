/* The configuration file: "key = value" lines, '#' comments. Unknown keys and unparsable values are
   errors that name the file, the line and the key: a typo must not fly with a default. */
#include "config.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Gain profiles: "default" is tuned on the rig's plant (seed 001 vehicle); "seed002" is the nested
   PI-PID of seed 002 (Table 2 outer PI 4.5/0.35, Table 3 inner PID 0.14/0.015/0.0025 in units of the
   throttle range per rad/s, here x1000 us). Keys after "profile" in a file override it. */
static int profile_apply(fc_config *c, const char *name)
{
    if (strcmp(name, "default") == 0) {
        c->angle_kp = 4.5; c->angle_ki = 0.35; c->angle_kd = 0;
        c->rate_kp = 40; c->rate_ki = 40; c->rate_kd = 0.5;
    } else if (strcmp(name, "seed002") == 0) {
        c->angle_kp = 4.5; c->angle_ki = 0.35; c->angle_kd = 0;
        c->rate_kp = 140; c->rate_ki = 15; c->rate_kd = 2.5;
    } else {
        return -1;
    }
    return 0;
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
    profile_apply(c, "default");
    c->yaw_rate_kp = 300; c->yaw_rate_ki = 30;
    c->alt_kp = 2.0; c->alt_ki = 0.03; c->alt_kd = 0.0; c->alt_kv = 3.0; c->baro_gate_m = 3.0; c->alt_sp_range_m = 5.0;
    c->acc_kp = 2.0; c->acc_ki = 0.5; c->acc_kd = 0.0;
    c->angle_limit = 100; c->alt_limit = 10;
    c->hover_us = 1511;
    c->max_angle_deg = 30; c->max_yaw_rate_dps = 90;
    for (int i = 0; i < 4; i++) { c->alpha[i] = 1; c->beta[i] = 0; }
    for (int i = 0; i < 3; i++) { c->acc_scale[i] = 1; c->mag_scale[i] = 1; }
    c->telemetry_every = 5;
}

struct key { const char *name; char kind; size_t off; int n; };
#define D(name, n) {#name, 'd', offsetof(fc_config, name), n}
#define I(name) {#name, 'i', offsetof(fc_config, name), 1}
#define S(name) {#name, 's', offsetof(fc_config, name), 1}

static const struct key keys[] = {
    S(i2c_path), I(mpu_addr), I(hmc_addr), I(baro_addr), S(rc_path), S(telemetry_path), I(pwm_chip),
    I(estimator), I(mixer), D(est_rate_hz, 1), D(ctrl_rate_hz, 1), I(defect_mixer_sign), I(defect_never_arm),
    I(gyro_fault_check), D(defect_crash_at, 1), D(kp_est, 1), D(ki_est, 1), D(angle_kp, 1), D(angle_ki, 1),
    D(angle_kd, 1), D(rate_kp, 1), D(rate_ki, 1), D(rate_kd, 1), D(yaw_rate_kp, 1), D(yaw_rate_ki, 1), D(alt_sp_range_m, 1),
    D(alt_kp, 1), D(alt_ki, 1), D(alt_kd, 1), D(alt_kv, 1), D(baro_gate_m, 1), D(acc_kp, 1), D(acc_ki, 1), D(acc_kd, 1), D(angle_limit, 1),
    D(alt_limit, 1), D(hover_us, 1), D(max_angle_deg, 1), D(max_yaw_rate_dps, 1), D(alpha, 4), D(beta, 4),
    D(acc_offset, 3), D(acc_scale, 3), D(mag_offset, 3), D(mag_scale, 3), I(telemetry_every),
};

int config_load(fc_config *c, const char *path, char *err, int errlen)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, (size_t)errlen, "%s: cannot open", path);
        return -1;
    }
    char line[512];
    for (int no = 1; fgets(line, sizeof line, f); no++) {
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        char name[64], value[256];
        if (sscanf(line, " %63[A-Za-z0-9_] = %255[^\n]", name, value) != 2) {
            if (strspn(line, " \t\r\n") == strlen(line))
                continue;
            snprintf(err, (size_t)errlen, "%s:%d: expected 'key = value'", path, no);
            fclose(f);
            return -1;
        }
        if (strcmp(name, "profile") == 0) {
            char pname[64];
            if (sscanf(value, "%63s", pname) != 1 || profile_apply(c, pname) < 0) {
                snprintf(err, (size_t)errlen, "%s:%d: profile expects default or seed002", path, no);
                fclose(f);
                return -1;
            }
            continue;
        }
        const struct key *k = NULL;
        for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
            if (strcmp(keys[i].name, name) == 0)
                k = &keys[i];
        if (!k) {
            snprintf(err, (size_t)errlen, "%s:%d: unknown key '%s'", path, no, name);
            fclose(f);
            return -1;
        }
        char *p = value, *end;
        int ok = 1;
        if (k->kind == 's') {
            size_t len = strcspn(value, " \t\r");
            ok = len > 0 && len < 64;
            if (ok) { memcpy((char *)c + k->off, value, len); ((char *)c + k->off)[len] = 0; }
        } else if (k->kind == 'i') {
            long v = strtol(p, &end, 0);
            ok = end != p && strspn(end, " \t\r") == strlen(end);
            if (ok) *(int *)((char *)c + k->off) = (int)v;
        } else {
            for (int j = 0; j < k->n && ok; j++) {
                double v = strtod(p, &end);
                ok = end != p;
                ((double *)((char *)c + k->off))[j] = v;
                p = end + strspn(end, " ,\t");
            }
            ok = ok && strspn(p, " \t\r") == strlen(p);
        }
        if (!ok) {
            snprintf(err, (size_t)errlen, "%s:%d: %s expects %s", path, no, name,
                     k->kind == 's' ? "a path" : k->kind == 'i' ? "an integer" : k->n > 1 ? "numbers" : "a number");
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    if (c->est_rate_hz < 10 || c->est_rate_hz > 2000 || c->ctrl_rate_hz < 10 || c->ctrl_rate_hz > c->est_rate_hz || c->estimator < 0 || c->estimator > 2 || c->mixer < 0 || c->mixer > 1 ||
        c->telemetry_every < 1 || !(c->alt_sp_range_m >= 0 && c->alt_sp_range_m <= 100)) {
        snprintf(err, (size_t)errlen, "%s: est_rate_hz must be 10..2000, ctrl_rate_hz 10..est_rate_hz, estimator 0..2, mixer 0..1, telemetry_every >= 1, alt_sp_range_m 0..100",
                 path);
        return -1;
    }
    return 0;
}
