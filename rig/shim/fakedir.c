/*
 * Directory streams on fake directories: glibc's readdir reads a descriptor with getdents64, which no
 * preload can redirect, so the shim lists them itself (opendir and fdopendir make the stream, in
 * dispatch.c); readdir, readdir64, rewinddir, dirfd and closedir tell one of these streams from a real
 * DIR by the list of those open. Part of rigshim.c (one translation unit): see its top comment.
 */

/* The pwm class's directories, listed as the kernel lists them: /sys/class/pwm holds pwmchip0, the chip
   export, npwm, unexport and pwmN for each exported channel, pwmN duty_cycle, enable, period and
   polarity. Only what the shim emulates is listed, so every name listed can be opened and stat'ed (a
   real chip also has device, power, subsystem and uevent, a channel capture, power and uevent).
   glibc's readdir reads a descriptor with getdents64, which no preload can redirect, so opendir and
   fdopendir on a fake give the shim's own stream; the calls taking a DIR tell one from a real DIR by
   the list of those open. The chip's channels are read when the stream opens or rewinds. */
struct fake_dir {
    struct fake_dir *next;
    int fd;
    struct target t;
    uint32_t exported; /* bit N: pwmN exported */
    long at;           /* the next entry */
    struct dirent64 ent;
};
_Static_assert(sizeof(struct dirent) == sizeof(struct dirent64), "struct dirent64 differs from struct dirent");
static struct fake_dir *fake_dirs;
static int n_fake_dirs;

static struct fake_dir *fake_dir_of(DIR *d)
{
    if (!__atomic_load_n(&n_fake_dirs, __ATOMIC_ACQUIRE))
        return NULL;
    pthread_mutex_lock(&lock);
    struct fake_dir *p = fake_dirs;
    while (p && (DIR *)p != d)
        p = p->next;
    pthread_mutex_unlock(&lock);
    return p;
}

static void dir_rewind(struct fake_dir *d)
{
    d->exported = 0;
    for (unsigned i = 0; i < shm->npwm && i < 32; i++)
        if (shm->pwm[i].exported)
            d->exported |= 1u << i;
    d->at = 0;
}

static DIR *dir_open(int fd, const struct target *t)
{
    struct fake_dir *d = calloc(1, sizeof *d);
    if (!d) {
        errno = ENOMEM;
        return NULL;
    }
    d->fd = fd;
    d->t = *t;
    dir_rewind(d);
    pthread_mutex_lock(&lock);
    d->next = fake_dirs;
    fake_dirs = d;
    __atomic_add_fetch(&n_fake_dirs, 1, __ATOMIC_RELEASE);
    pthread_mutex_unlock(&lock);
    return (DIR *)d;
}

/* Entry i of the directory into e (0: past the end). */
static int dir_entry(const struct fake_dir *d, long i, struct dirent64 *e)
{
    struct target c = d->t; /* what the entry names */
    const char *name = NULL;
    char buf[32];
    if (i < 2) {
        name = i ? ".." : ".";
        if (i)
            c.channel = c.channel >= 0 ? -1 : c.channel - 1;
    } else if (d->t.channel <= -2) {
        if (i > 2)
            return 0;
        c.channel = d->t.channel + 1;
        snprintf(buf, sizeof buf, "pwmchip%d", pwm_chip);
        name = c.channel == -1 ? buf : "pwm";
    } else if (d->t.channel == -1 && i < 2 + A_PERIOD) {
        c.kind = K_PWM_ATTR;
        c.attr = (enum pwm_attr)(i - 2);
        name = attr_names[c.attr];
    } else if (d->t.channel == -1) {
        long k = i - 2 - A_PERIOD;
        for (c.channel = 0; c.channel < 32; c.channel++)
            if ((d->exported >> c.channel & 1u) && k-- == 0)
                break;
        if (c.channel == 32)
            return 0;
        snprintf(buf, sizeof buf, "pwm%d", c.channel);
        name = buf;
    } else {
        if (i >= 2 + N_ATTRS - A_PERIOD)
            return 0;
        c.kind = K_PWM_ATTR;
        c.attr = (enum pwm_attr)(A_PERIOD + i - 2);
        name = attr_names[c.attr];
    }
    e->d_ino = target_ino(&c);
    e->d_off = i + 1;
    e->d_reclen = sizeof *e;
    e->d_type = c.kind == K_PWM_DIR ? DT_DIR : DT_REG;
    snprintf(e->d_name, sizeof e->d_name, "%s", name);
    return 1;
}

static struct dirent64 *dir_read(struct fake_dir *d)
{
    if (!dir_entry(d, d->at, &d->ent))
        return NULL; /* the end: errno unchanged */
    d->at++;
    return &d->ent;
}

EXPORT struct dirent *readdir(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    return d ? (struct dirent *)dir_read(d) : LOAD(readdir)(dir);
}

EXPORT struct dirent64 *readdir64(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    return d ? dir_read(d) : LOAD(readdir64)(dir);
}

EXPORT int closedir(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    if (!d)
        return LOAD(closedir)(dir);
    pthread_mutex_lock(&lock);
    for (struct fake_dir **p = &fake_dirs; *p; p = &(*p)->next)
        if (*p == d) {
            *p = d->next;
            break;
        }
    __atomic_sub_fetch(&n_fake_dirs, 1, __ATOMIC_RELEASE);
    pthread_mutex_unlock(&lock);
    int r = close(d->fd);
    free(d);
    return r;
}

EXPORT int dirfd(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    return d ? d->fd : LOAD(dirfd)(dir);
}

EXPORT void rewinddir(DIR *dir)
{
    struct fake_dir *d = fake_dir_of(dir);
    if (d)
        dir_rewind(d);
    else
        LOAD(rewinddir)(dir);
}
