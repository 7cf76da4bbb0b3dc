/* The configuration file (Linux): "key = value" lines, '#' comments. Unknown keys and unparsable values
   are errors that name the file, the line and the key: a typo must not fly with a default. */
#include "config.h"

#include <math.h>

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "config_keys.h"

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
            if (sscanf(value, "%63s", pname) != 1 || config_profile(c, config_profile_index(pname)) < 0) {
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
                ((real *)((char *)c + k->off))[j] = (real)v;
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
    if (config_check(c) < 0) {
        snprintf(err, (size_t)errlen, "%s: ctrl_rate_hz (%g) must be at most est_rate_hz (%g)", path,
                 (double)c->ctrl_rate_hz, (double)c->est_rate_hz);
        return -1;
    }
    return 0;
}
