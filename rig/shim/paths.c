/*
 * What a path names: classify turns a path into a target (an emulated bus, a PWM attribute or
 * directory, a serial path redirected to a pty, or nothing of ours), and a target has the kernel's
 * name for it and what stat shows for it. Part of rigshim.c (one translation unit): see its top
 * comment.
 */

enum kind { K_NONE, K_I2C, K_PWM_ATTR, K_PWM_DIR, K_SERIAL };
enum pwm_attr { A_EXPORT, A_UNEXPORT, A_NPWM, A_PERIOD, A_DUTY, A_ENABLE, A_POLARITY };
#define N_ATTRS (A_POLARITY + 1)
static const char *const attr_names[N_ATTRS] = {"export", "unexport", "npwm", "period", "duty_cycle", "enable",
                                                "polarity"};

struct target {
    enum kind kind;
    int bus;         /* K_I2C */
    int channel;     /* K_PWM_*: -1 for the chip itself, -2 for /sys/class/pwm, -3 for its .. */
    enum pwm_attr attr;
    const char *to;  /* K_SERIAL: the pty */
};

static int parse_uint(const char *s, const char **end)
{
    if (*s < '0' || *s > '9')
        return -1;
    long v = 0;
    while (*s >= '0' && *s <= '9' && v < 100000)
        v = v * 10 + (*s++ - '0');
    *end = s;
    return (int)v;
}

/* The attribute "/name" among from..to-1, or N_ATTRS. */
static int attr_named(const char *rest, int from, int to)
{
    for (int a = from; rest[0] == '/' && a < to; a++)
        if (strcmp(rest + 1, attr_names[a]) == 0)
            return a;
    return N_ATTRS;
}

/* What a path names. A pwmN path exists only while the channel is exported, unless any_channel (a
   descriptor inherited across exec names its file even after an unexport, as an open file does). */
static struct target classify_path(const char *path, int any_channel)
{
    struct target t = {.kind = K_NONE};
    if (!active || !path)
        return t;
    const char *rest = "";
    if (strncmp(path, "/dev/i2c-", 9) == 0) {
        int n = parse_uint(path + 9, &rest);
        if (n >= 0 && n < 32 && *rest == 0 && (i2c_buses_mask >> n & 1u)) {
            t.kind = K_I2C;
            t.bus = n;
        }
        return t;
    }
    for (int i = 0; i < n_serial; i++)
        if (strcmp(path, serial_map[i].from) == 0) {
            t.kind = K_SERIAL;
            t.to = serial_map[i].to;
            return t;
        }
    size_t len = strlen(path);
    int up = len > 16 && strcmp(path + len - 3, "/..") == 0, here = len > 15 && strcmp(path + len - 2, "/.") == 0;
    if ((up || here) && strncmp(path, "/sys/class/pwm/", 15) == 0 && len < PATH_MAX) {
        /* the "." and ".." a listing shows (ls -la): the directory, or the one it is listed in (for
           /sys/class/pwm/.., a /sys/class that holds pwm alone: ls -l asks its extended attributes
           by this path, which only the shim knows) */
        char dir[PATH_MAX];
        memcpy(dir, path, len - (up ? 3 : 2));
        dir[len - (up ? 3 : 2)] = 0;
        struct target d = classify_path(dir, any_channel);
        if (d.kind != K_PWM_DIR || (up && d.channel == -3))
            return t;
        if (up)
            d.channel = d.channel >= 0 ? -1 : d.channel - 1;
        return d;
    }
    if (strcmp(path, "/sys/class/pwm") == 0 || strcmp(path, "/sys/class/pwm/") == 0) {
        t.kind = K_PWM_DIR;
        t.channel = -2;
        return t;
    }
    if (strncmp(path, "/sys/class/pwm/pwmchip", 22) != 0)
        return t;
    int chip = parse_uint(path + 22, &rest);
    if (chip != pwm_chip || !shm)
        return t;
    t.channel = -1;
    if (*rest == 0 || strcmp(rest, "/") == 0) {
        t.kind = K_PWM_DIR;
        return t;
    }
    int a = attr_named(rest, A_EXPORT, A_PERIOD);
    if (a != N_ATTRS) {
        t.kind = K_PWM_ATTR;
        t.attr = (enum pwm_attr)a;
        return t;
    }
    if (strncmp(rest, "/pwm", 4) != 0)
        return t;
    int ch = parse_uint(rest + 4, &rest);
    if (ch < 0 || ch >= (int)shm->npwm || (!any_channel && !shm->pwm[ch].exported))
        return t; /* not exported: the file does not exist (ENOENT from the real call) */
    t.channel = ch;
    if (*rest == 0 || strcmp(rest, "/") == 0) {
        t.kind = K_PWM_DIR;
        return t;
    }
    a = attr_named(rest, A_PERIOD, N_ATTRS);
    if (a != N_ATTRS) {
        t.kind = K_PWM_ATTR;
        t.attr = (enum pwm_attr)a;
    }
    return t;
}

static struct target classify(const char *path) { return classify_path(path, 0); }

/* The path a target is known by (the kernel's name for the file). */
static void target_path(const struct target *t, char *buf, size_t n)
{
    const char *sep = t->kind == K_PWM_ATTR ? "/" : "", *attr = t->kind == K_PWM_ATTR ? attr_names[t->attr] : "";
    if (t->kind == K_I2C)
        snprintf(buf, n, "/dev/i2c-%d", t->bus);
    else if (t->channel <= -2)
        snprintf(buf, n, t->channel == -2 ? "/sys/class/pwm" : "/sys/class");
    else if (t->channel == -1)
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d%s%s", pwm_chip, sep, attr);
    else
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d/pwm%d%s%s", pwm_chip, t->channel, sep, attr);
}

/* Only absolute paths are redirected (openat with a directory and a relative path passes through). */
static struct target classify_abs(const char *path)
{
    return path && path[0] == '/' ? classify(path) : (struct target){.kind = K_NONE};
}

static int is_empty(const char *path) { return path && path[0] == 0; }

static ino_t target_ino(const struct target *t)
{
    if (t->kind == K_I2C)
        return 1000 + (ino_t)t->bus;
    if (t->kind == K_PWM_DIR)
        return 2000 + (ino_t)(t->channel + 2); /* channel -2 is /sys/class/pwm, -3 its parent */
    return 3000 + (ino_t)(t->channel + 1) * 8 + (ino_t)t->attr;
}

/* A path the kernel would have that we only pretend: make it ENOENT-proof for stat/access. */
static void fill_stat(const struct target *t, struct stat *st)
{
    memset(st, 0, sizeof *st);
    st->st_uid = getuid();
    st->st_gid = getgid();
    st->st_nlink = 1;
    st->st_blksize = 4096;
    if (t->kind == K_I2C) {
        st->st_mode = S_IFCHR | 0660;
        st->st_rdev = makedev(I2C_MAJOR, t->bus);
        st->st_dev = makedev(0, 5);
    } else if (t->kind == K_PWM_DIR) {
        st->st_mode = S_IFDIR | 0755;
        st->st_nlink = 2;
    } else {
        int wo = t->attr == A_EXPORT || t->attr == A_UNEXPORT, ro = t->attr == A_NPWM;
        st->st_mode = S_IFREG | (wo ? 0200 : ro ? 0444 : 0644);
        st->st_size = 4096;
    }
    st->st_ino = target_ino(t);
}
