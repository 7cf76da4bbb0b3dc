/* The configuration file: "key = value" lines, '#' comments. Unknown keys and unparsable values are
   errors that name the file, the line and the key: a typo must not fly with a default. */
#include "config.h"

#include <math.h>

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "config_keys.h"

/* Gain profiles: "default" is tuned on the rig's plant (seed 001 vehicle); "seed002" is the nested
   PI-PID of seed 002 (Table 2 outer PI 4.5/0.35, Table 3 inner PID 0.14/0.015/0.0025 in units of the
   throttle range per rad/s, here x1000 us). Keys after "profile" in a file override it. */
static int profile_apply(fc_config *c, const char *name)
{
    if (strcmp(name, "default") == 0) {
        c->angle_kp = 4.5;
        c->angle_ki = 0.35;
        c->angle_kd = 0;
        c->rate_kp = 40;
        c->rate_ki = 40;
        c->rate_kd = 0.5;
    } else if (strcmp(name, "seed002") == 0) {
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
}

struct key {
    const char *name;
    char kind;
    size_t off;
    int n;
    double low, high;
};
#define ANY NAN /* no limit on this side */
#define FC_KEY(name, kind, n, low, high) { #name, #kind[0], offsetof(fc_config, name), n, low, high },
static const struct key keys[] = { FC_CONFIG_KEYS(FC_KEY) };
#undef FC_KEY

static int in_range(const struct key *k, double v)
{
    return (isnan(k->low) || v >= k->low) && (isnan(k->high) || v <= k->high);
}

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
#define PROFILE(p) " " #p
                snprintf(err, (size_t)errlen, "%s:%d: profile expects one of:" FC_PROFILES(PROFILE), path, no);
#undef PROFILE
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
        int ok = 1, inside = 1;
        if (k->kind == 'S') {
            size_t len = strcspn(value, " \t\r");
            ok = len > 0 && len < 64;
            if (ok) {
                memcpy((char *)c + k->off, value, len);
                ((char *)c + k->off)[len] = 0;
            }
        } else if (k->kind == 'I') {
            long v = strtol(p, &end, 0);
            ok = end != p && strspn(end, " \t\r") == strlen(end);
            inside = in_range(k, (double)v);
            if (ok)
                *(int *)((char *)c + k->off) = (int)v;
        } else {
            for (int j = 0; j < k->n && ok; j++) {
                double v = strtod(p, &end);
                ok = end != p && isfinite(v);
                inside = inside && in_range(k, v);
                ((double *)((char *)c + k->off))[j] = v;
                p = end + strspn(end, " ,\t");
            }
            ok = ok && strspn(p, " \t\r") == strlen(p);
        }
        if (!ok) {
            snprintf(err, (size_t)errlen, "%s:%d: %s expects %s", path, no, name,
                     k->kind == 'S'   ? "a path"
                     : k->kind == 'I' ? "an integer"
                     : k->n > 1       ? "numbers"
                                      : "a number");
            fclose(f);
            return -1;
        }
        if (!inside) {
            if (isnan(k->high))
                snprintf(err, (size_t)errlen, "%s:%d: %s must be >= %g", path, no, name, k->low);
            else if (isnan(k->low))
                snprintf(err, (size_t)errlen, "%s:%d: %s must be <= %g", path, no, name, k->high);
            else
                snprintf(err, (size_t)errlen, "%s:%d: %s must be in %g..%g", path, no, name, k->low, k->high);
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    if (c->ctrl_rate_hz > c->est_rate_hz) {
        snprintf(err, (size_t)errlen, "%s: ctrl_rate_hz (%g) must be at most est_rate_hz (%g)", path, c->ctrl_rate_hz,
                 c->est_rate_hz);
        return -1;
    }
    return 0;
}
