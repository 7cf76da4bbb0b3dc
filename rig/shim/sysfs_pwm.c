/*
 * The device kinds K_PWM_ATTR and K_PWM_DIR: the sysfs PWM class (/sys/class/pwm, the chip
 * RIG_PWM_CHIP, its channels). An attribute's state lives in the shared page; each accepted write is a
 * notice to the session, which costs the DUT no round trip. Its directories list as the kernel's do.
 * Their rows in kinds[] (rigshim.c) name the operations; the attributes' row classifies the paths of
 * both. Part of rigshim.c (one translation unit): see its top comment.
 */

static int pwm_chip;

enum pwm_attr { A_EXPORT, A_UNEXPORT, A_NPWM, A_PERIOD, A_DUTY, A_ENABLE, A_POLARITY };
#define N_ATTRS (A_POLARITY + 1)
static const char *const attr_names[N_ATTRS] = { "export",     "unexport", "npwm",    "period",
                                                 "duty_cycle", "enable",   "polarity" };

static void pwm_init(void)
{
    const char *chip = getenv("RIG_PWM_CHIP");
    pwm_chip = chip ? atoi(chip) : 0;
}

/* The attribute "/name" among from..to-1, or N_ATTRS. */
static int attr_named(const char *rest, int from, int to)
{
    for (int a = from; rest[0] == '/' && a < to; a++)
        if (strcmp(rest + 1, attr_names[a]) == 0)
            return a;
    return N_ATTRS;
}

/* Everything under /sys/class/pwm is the class's to decide. A pwmN path exists only while the channel
   is exported, unless inherited (a descriptor inherited across exec names its file even after an
   unexport, as an open file does). */
static int pwm_claim(const char *path, int inherited, struct target *t)
{
    if (strncmp(path, "/sys/class/pwm", 14) != 0)
        return 0;
    const char *rest = "";
    size_t len = strlen(path);
    int up = len > 16 && strcmp(path + len - 3, "/..") == 0, here = len > 15 && strcmp(path + len - 2, "/.") == 0;
    if ((up || here) && strncmp(path, "/sys/class/pwm/", 15) == 0 && len < PATH_MAX) {
        /* the "." and ".." a listing shows (ls -la): the directory, or the one it is listed in (for
           /sys/class/pwm/.., a /sys/class that holds pwm alone: ls -l asks its extended attributes
           by this path, which only the shim knows) */
        char dir[PATH_MAX];
        memcpy(dir, path, len - (up ? 3 : 2));
        dir[len - (up ? 3 : 2)] = 0;
        struct target d = classify_path(dir, inherited);
        if (d.kind != K_PWM_DIR || (up && d.channel == -3))
            return 1;
        if (up)
            d.channel = d.channel >= 0 ? -1 : d.channel - 1;
        *t = d;
        return 1;
    }
    if (strcmp(path, "/sys/class/pwm") == 0 || strcmp(path, "/sys/class/pwm/") == 0) {
        t->kind = K_PWM_DIR;
        t->channel = -2;
        return 1;
    }
    if (strncmp(path, "/sys/class/pwm/pwmchip", 22) != 0)
        return 1;
    int chip = parse_uint(path + 22, &rest);
    if (chip != pwm_chip || !shm)
        return 1;
    t->channel = -1;
    if (*rest == 0 || strcmp(rest, "/") == 0) {
        t->kind = K_PWM_DIR;
        return 1;
    }
    int a = attr_named(rest, A_EXPORT, A_PERIOD);
    if (a != N_ATTRS) {
        t->kind = K_PWM_ATTR;
        t->attr = a;
        return 1;
    }
    if (strncmp(rest, "/pwm", 4) != 0)
        return 1;
    int ch = parse_uint(rest + 4, &rest);
    if (ch < 0 || ch >= (int)shm->npwm || (!inherited && !shm->pwm[ch].exported))
        return 1; /* not exported: the file does not exist (ENOENT from the real call) */
    t->channel = ch;
    if (*rest == 0 || strcmp(rest, "/") == 0) {
        t->kind = K_PWM_DIR;
        return 1;
    }
    a = attr_named(rest, A_PERIOD, N_ATTRS);
    if (a != N_ATTRS) {
        t->kind = K_PWM_ATTR;
        t->attr = a;
    }
    return 1;
}

static void pwm_dir_name(const struct target *t, char *buf, size_t n)
{
    if (t->channel <= -2)
        snprintf(buf, n, t->channel == -2 ? "/sys/class/pwm" : "/sys/class");
    else if (t->channel == -1)
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d", pwm_chip);
    else
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d/pwm%d", pwm_chip, t->channel);
}

static void pwm_attr_name(const struct target *t, char *buf, size_t n)
{
    if (t->channel == -1)
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d/%s", pwm_chip, attr_names[t->attr]);
    else
        snprintf(buf, n, "/sys/class/pwm/pwmchip%d/pwm%d/%s", pwm_chip, t->channel, attr_names[t->attr]);
}

static ino_t pwm_ino(const struct target *t)
{
    if (t->kind == K_PWM_DIR)
        return 2000 + (ino_t)(t->channel + 2); /* channel -2 is /sys/class/pwm, -3 its parent */
    return 3000 + (ino_t)(t->channel + 1) * 8 + (ino_t)t->attr;
}

static void pwm_dir_fill_stat(const struct target *t, struct stat *st)
{
    stat_common(st, pwm_ino(t));
    st->st_mode = S_IFDIR | 0755;
    st->st_nlink = 2;
}

/* export and unexport are write-only (root may open them for reading too, and reads EIO), npwm
   read-only. */
static int attr_write_only(int attr) { return attr == A_EXPORT || attr == A_UNEXPORT; }
static int attr_read_only(int attr) { return attr == A_NPWM; }

static void pwm_attr_fill_stat(const struct target *t, struct stat *st)
{
    stat_common(st, pwm_ino(t));
    int wo = attr_write_only(t->attr), ro = attr_read_only(t->attr);
    st->st_mode = S_IFREG | (wo ? 0200 : ro ? 0444 : 0644);
    st->st_size = 4096;
}

static int pwm_dir_open(const struct target *t, int flags, mode_t mode)
{
    (void)mode;
    if ((flags & O_ACCMODE) != O_RDONLY || (flags & O_CREAT))
        return errno_ret(EISDIR);
    return open_fake(t, flags);
}

static int pwm_attr_open(const struct target *t, int flags, mode_t mode)
{
    (void)mode;
    int acc = flags & O_ACCMODE;
    if (flags & O_DIRECTORY)
        return errno_ret(ENOTDIR);
    int wo = attr_write_only(t->attr), ro = attr_read_only(t->attr);
    if ((wo && acc != O_WRONLY && getuid() != 0) || (ro && acc != O_RDONLY))
        return errno_ret(EACCES);
    return open_fake(t, flags);
}

static int parse_u64(const char *buf, size_t n, uint64_t *out)
{
    char s[32];
    if (n == 0 || n >= sizeof s)
        return -1;
    memcpy(s, buf, n);
    s[n] = 0;
    if (s[n - 1] == '\n')
        s[--n] = 0; /* sysfs accepts one trailing newline, as echo writes */
    if (n == 0 || s[0] == '-' || s[0] == '+' || s[0] == ' ')
        return -1;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 0);
    if (errno || *end)
        return -1;
    *out = v;
    return 0;
}

static int streq_nl(const char *buf, size_t n, const char *word)
{
    size_t w = strlen(word);
    return (n == w || (n == w + 1 && buf[w] == '\n')) && memcmp(buf, word, w) == 0;
}

static ssize_t pwm_attr_write(struct fake *f, const void *buf, size_t n)
{
    n = n > SYSFS_PAGE ? SYSFS_PAGE : n;
    if (copy_in(xfer_buf, buf, n))
        return errno_ret(EFAULT);
    const char *s = (const char *)xfer_buf;
    uint64_t v = 0;
    struct rig_pwm_msg msg = { .chip = (uint16_t)pwm_chip, .channel = (uint16_t)(f->t.channel < 0 ? 0 : f->t.channel) };
    LOAD(pthread_mutex_lock)(&lock);
    int err = 0;
    struct rig_pwm_state *p = f->t.channel >= 0 ? &shm->pwm[f->t.channel] : NULL;
    switch ((enum pwm_attr)f->t.attr) {
    case A_EXPORT:
    case A_UNEXPORT:
        if (parse_u64(s, n, &v) < 0 || v >= shm->npwm) {
            err = v >= shm->npwm ? ENODEV : EINVAL;
            break;
        }
        p = &shm->pwm[v];
        if (f->t.attr == A_EXPORT && p->exported)
            err = EBUSY;
        else if (f->t.attr == A_UNEXPORT && !p->exported)
            err = ENODEV;
        else if (f->t.attr == A_EXPORT)
            p->exported = 1;
        else
            *p = (struct rig_pwm_state){ 0 }; /* unexport turns the output off */
        msg.channel = (uint16_t)v;
        msg.attr = f->t.attr == A_EXPORT ? RIG_PWM_EXPORT : RIG_PWM_UNEXPORT;
        break;
    case A_NPWM:
        err = EACCES;
        break;
    case A_PERIOD:
    case A_DUTY:
        if (!p->exported)
            err = ENODEV;
        else if (parse_u64(s, n, &v) < 0)
            err = EINVAL;
        else if (f->t.attr == A_PERIOD ? (v < p->duty_ns || (v == 0 && p->enabled)) : v > p->period_ns)
            err = EINVAL; /* pwm_apply_state: duty above period, or an enabled zero period */
        else if (f->t.attr == A_PERIOD)
            p->period_ns = v;
        else
            p->duty_ns = v;
        msg.attr = f->t.attr == A_PERIOD ? RIG_PWM_PERIOD : RIG_PWM_DUTY;
        break;
    case A_ENABLE:
        if (!p->exported)
            err = ENODEV;
        else if (parse_u64(s, n, &v) < 0 || v > 1)
            err = EINVAL;
        else if (v == 1 && p->period_ns == 0)
            err = EINVAL;
        else
            p->enabled = (uint32_t)v;
        msg.attr = RIG_PWM_ENABLE;
        break;
    case A_POLARITY:
        if (!p->exported)
            err = ENODEV;
        else if (streq_nl(s, n, "normal"))
            v = 0;
        else if (streq_nl(s, n, "inversed"))
            v = 1;
        else
            err = EINVAL;
        if (!err)
            p->inversed = (uint32_t)v;
        msg.attr = RIG_PWM_POLARITY;
        break;
    }
    msg.value = v;
    if (!err) {
        ensure_connected();
        hold_msg(RIG_MSG_PWM, &msg, sizeof msg); /* a notice: the DUT never waits for it */
    }
    pthread_mutex_unlock(&lock);
    return err ? errno_ret(err) : (ssize_t)n;
}

static ssize_t pwm_attr_read(struct fake *f, void *buf, size_t n, off_t *pos)
{
    char text[32];
    struct rig_pwm_state *p = f->t.channel >= 0 ? &shm->pwm[f->t.channel] : NULL;
    switch ((enum pwm_attr)f->t.attr) {
    case A_EXPORT:
    case A_UNEXPORT:
        return errno_ret(EIO);
    case A_NPWM:
        snprintf(text, sizeof text, "%u\n", shm->npwm);
        break;
    case A_PERIOD:
        snprintf(text, sizeof text, "%llu\n", (unsigned long long)p->period_ns);
        break;
    case A_DUTY:
        snprintf(text, sizeof text, "%llu\n", (unsigned long long)p->duty_ns);
        break;
    case A_ENABLE:
        snprintf(text, sizeof text, "%u\n", p->enabled);
        break;
    case A_POLARITY:
        snprintf(text, sizeof text, "%s\n", p->inversed ? "inversed" : "normal");
        break;
    }
    size_t len = strlen(text);
    if (*pos < 0 || (size_t)*pos >= len)
        return 0;
    size_t k = len - (size_t)*pos < n ? len - (size_t)*pos : n;
    if (copy_out(buf, text + *pos, k))
        return errno_ret(EFAULT);
    *pos += (off_t)k;
    return (ssize_t)k;
}

static ssize_t pwm_dir_read(struct fake *f, void *buf, size_t n, off_t *pos)
{
    (void)f, (void)buf, (void)n, (void)pos;
    return errno_ret(EISDIR);
}

/* The pwm class's directories, listed as the kernel lists them: /sys/class/pwm holds pwmchip0, the chip
   export, npwm, unexport and pwmN for each exported channel, pwmN duty_cycle, enable, period and
   polarity. Only what the shim emulates is listed, so every name listed can be opened and stat'ed (a
   real chip also has device, power, subsystem and uevent, a channel capture, power and uevent). The
   chip's channels are read when the stream opens or rewinds. */
static uint32_t pwm_dir_start(const struct target *dir)
{
    (void)dir;
    uint32_t exported = 0;
    for (unsigned i = 0; i < shm->npwm && i < 32; i++)
        if (shm->pwm[i].exported)
            exported |= 1u << i;
    return exported;
}

/* Entry i of the directory into e (0: past the end), with the channels exported when the stream opened
   or rewound. */
static int pwm_dir_entry(const struct target *dir, uint32_t exported, long i, struct dirent64 *e)
{
    struct target c = *dir; /* what the entry names */
    const char *name = NULL;
    char buf[32];
    if (i < 2) {
        name = i ? ".." : ".";
        if (i)
            c.channel = c.channel >= 0 ? -1 : c.channel - 1;
    } else if (dir->channel <= -2) {
        if (i > 2)
            return 0;
        c.channel = dir->channel + 1;
        snprintf(buf, sizeof buf, "pwmchip%d", pwm_chip);
        name = c.channel == -1 ? buf : "pwm";
    } else if (dir->channel == -1 && i < 2 + A_PERIOD) {
        c.kind = K_PWM_ATTR;
        c.attr = (int)(i - 2);
        name = attr_names[c.attr];
    } else if (dir->channel == -1) {
        long k = i - 2 - A_PERIOD;
        for (c.channel = 0; c.channel < 32; c.channel++)
            if ((exported >> c.channel & 1u) && k-- == 0)
                break;
        if (c.channel == 32)
            return 0;
        snprintf(buf, sizeof buf, "pwm%d", c.channel);
        name = buf;
    } else {
        if (i >= 2 + N_ATTRS - A_PERIOD)
            return 0;
        c.kind = K_PWM_ATTR;
        c.attr = (int)(A_PERIOD + i - 2);
        name = attr_names[c.attr];
    }
    e->d_ino = pwm_ino(&c);
    e->d_off = i + 1;
    e->d_reclen = sizeof *e;
    e->d_type = c.kind == K_PWM_DIR ? DT_DIR : DT_REG;
    snprintf(e->d_name, sizeof e->d_name, "%s", name);
    return 1;
}
