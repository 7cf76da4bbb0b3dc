/*
 * The interposed calls that may name a device: on a path (open and friends, fopen, opendir, the stat
 * family, access) or on a descriptor (read, write, pread, pwrite, lseek, ioctl, fstat, fdopendir, the
 * copies between descriptors). Part of rigshim.c (one translation unit): see its top comment.
 */

#define OPEN_MODE(flags, mode)                                                                                         \
    do {                                                                                                               \
        if ((flags) & (O_CREAT | __O_TMPFILE)) {                                                                       \
            va_list ap;                                                                                                \
            va_start(ap, flags);                                                                                       \
            mode = va_arg(ap, mode_t);                                                                                 \
            va_end(ap);                                                                                                \
        }                                                                                                              \
    } while (0)

static int redirect_open(const struct target *t, int flags, mode_t mode)
{
    if (t->kind == K_SERIAL)
        return LOAD(open)(t->to, flags, mode);
    return open_fake(t, flags);
}

EXPORT int open(const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(open)(path, flags, mode);
}

EXPORT int open64(const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(open64)(path, flags, mode);
}

EXPORT int openat(int dirfd, const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(openat)(dirfd, path, flags, mode);
}

EXPORT int openat64(int dirfd, const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, mode) : LOAD(openat64)(dirfd, path, flags, mode);
}

EXPORT int __open_2(const char *path, int flags)
{
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__open_2)(path, flags);
}

EXPORT int __open64_2(const char *path, int flags)
{
    struct target t = classify(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__open64_2)(path, flags);
}

EXPORT int __openat_2(int dirfd, const char *path, int flags)
{
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__openat_2)(dirfd, path, flags);
}

EXPORT int __openat64_2(int dirfd, const char *path, int flags)
{
    struct target t = classify_abs(path);
    return t.kind ? redirect_open(&t, flags, 0) : LOAD(__openat64_2)(dirfd, path, flags);
}

static FILE *redirect_fopen(const struct target *t, const char *mode, FILE *(*real)(const char *, const char *))
{
    if (t->kind == K_SERIAL)
        return real(t->to, mode);
    int flags = strchr(mode, '+') ? O_RDWR : mode[0] == 'r' ? O_RDONLY : O_WRONLY;
    if (strchr(mode, 'e'))
        flags |= O_CLOEXEC;
    int fd = open_fake(t, flags);
    if (fd < 0)
        return NULL;
    cookie_io_functions_t io = {cookie_read, cookie_write, cookie_seek, cookie_close};
    FILE *fp = fopencookie((void *)(intptr_t)fd, mode, io);
    if (!fp)
        close(fd);
    return fp;
}

EXPORT FILE *fopen(const char *path, const char *mode)
{
    struct target t = classify(path);
    return t.kind && t.kind != K_I2C ? redirect_fopen(&t, mode, LOAD(fopen)) : LOAD(fopen)(path, mode);
}

EXPORT FILE *fopen64(const char *path, const char *mode)
{
    struct target t = classify(path);
    return t.kind && t.kind != K_I2C ? redirect_fopen(&t, mode, LOAD(fopen64)) : LOAD(fopen64)(path, mode);
}

/* ---------------------------------------------------------------- copies between descriptors */

/* copy_file_range (coreutils cat and cp, when both ends look like regular files): sysfs and i2c-dev
   share no file system with anything, so the kernel answers EXDEV and the caller falls back to read
   and write, which the shim sees. (Into the backing file the bytes would be lost.) */
EXPORT ssize_t copy_file_range(int in, off64_t *in_off, int out, off64_t *out_off, size_t len, unsigned int flags)
{
    if (fake_of(in) || fake_of(out))
        return errno_ret(EXDEV);
    return LOAD(copy_file_range)(in, in_off, out, out_off, len, flags);
}

/* sendfile (Python's shutil.copyfile) with a PWM attribute at either end: the kernel's copy, up to a
   page per call, through the shim's read and write. i2c-dev cannot splice: EINVAL. */
static ssize_t sendfile_fake(int out, int in, off64_t *off, size_t count)
{
    struct fake *fi = fake_of(in), *fo = fake_of(out);
    if ((fi && fi->t.kind != K_PWM_ATTR) || (fo && fo->t.kind != K_PWM_ATTR))
        return errno_ret(EINVAL);
    char buf[4096];
    size_t n = count < sizeof buf ? count : sizeof buf;
    off_t at = off ? *off : fi ? fi->pos : LOAD(lseek)(in, 0, SEEK_CUR), next = at;
    if (at < 0)
        return -1;
    ssize_t k = fi ? fake_read(fi, buf, n, &next) : LOAD(pread)(in, buf, n, at);
    if (k <= 0)
        return k;
    ssize_t w = fo ? fake_write(fo, buf, (size_t)k) : write(out, buf, (size_t)k);
    if (w <= 0)
        return w;
    at += w;
    if (off)
        *off = at;
    else if (fi)
        fi->pos = at;
    else
        LOAD(lseek)(in, at, SEEK_SET);
    return w;
}

EXPORT ssize_t sendfile(int out, int in, off_t *off, size_t count)
{
    if (fake_of(in) || fake_of(out))
        return sendfile_fake(out, in, (off64_t *)off, count);
    return LOAD(sendfile)(out, in, off, count);
}

EXPORT ssize_t sendfile64(int out, int in, off64_t *off, size_t count)
{
    if (fake_of(in) || fake_of(out))
        return sendfile_fake(out, in, off, count);
    return LOAD(sendfile64)(out, in, off, count);
}

/* ---------------------------------------------------------------- directories */

EXPORT DIR *opendir(const char *path)
{
    struct target t = classify(path);
    if (t.kind == K_NONE || t.kind == K_SERIAL)
        return LOAD(opendir)(path);
    if (t.kind != K_PWM_DIR) {
        errno = ENOTDIR;
        return NULL;
    }
    int fd = open_fake(&t, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    DIR *d = dir_open(fd, &t);
    if (!d)
        close(fd);
    return d;
}

EXPORT DIR *fdopendir(int fd)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(fdopendir)(fd);
    if (f->t.kind != K_PWM_DIR) {
        errno = ENOTDIR;
        return NULL;
    }
    return dir_open(fd, &f->t);
}

/* ---------------------------------------------------------------- stat and access */

static int stat_target(const char *path, struct stat *st, int (*real)(const char *, struct stat *))
{
    struct target t = classify(path);
    if (t.kind == K_SERIAL)
        return real(t.to, st);
    if (t.kind) {
        fill_stat(&t, st);
        return 0;
    }
    return real(path, st);
}

/* struct stat64 is struct stat on the 64-bit targets we build for; the casts below rely on it. */
_Static_assert(sizeof(struct stat) == sizeof(struct stat64), "struct stat64 differs from struct stat");
_Static_assert(sizeof(off_t) == sizeof(off64_t), "off64_t differs from off_t");
typedef int (*stat_fn)(const char *, struct stat *);
typedef int (*fstat_fn)(int, struct stat *);
typedef int (*fstatat_fn)(int, const char *, struct stat *, int);

EXPORT int stat(const char *path, struct stat *st) { return stat_target(path, st, LOAD(stat)); }
EXPORT int stat64(const char *path, struct stat64 *st) { return stat_target(path, (struct stat *)st, (stat_fn)LOAD(stat64)); }
EXPORT int lstat(const char *path, struct stat *st) { return stat_target(path, st, LOAD(lstat)); }
EXPORT int lstat64(const char *path, struct stat64 *st) { return stat_target(path, (struct stat *)st, (stat_fn)LOAD(lstat64)); }

static int fstat_fake(int fd, struct stat *st, int (*real)(int, struct stat *))
{
    struct fake *f = fake_of(fd);
    if (f) {
        fill_stat(&f->t, st);
        return 0;
    }
    return real(fd, st);
}

EXPORT int fstat(int fd, struct stat *st) { return fstat_fake(fd, st, LOAD(fstat)); }
EXPORT int fstat64(int fd, struct stat64 *st) { return fstat_fake(fd, (struct stat *)st, (fstat_fn)LOAD(fstat64)); }

static int fstatat_target(int dirfd, const char *path, struct stat *st, int flags,
                          int (*real)(int, const char *, struct stat *, int))
{
    if (is_empty(path) && (flags & AT_EMPTY_PATH))
        return fake_of(dirfd) ? (fill_stat(&fake_of(dirfd)->t, st), 0) : real(dirfd, path, st, flags);
    struct target t = classify_abs(path);
    if (t.kind == K_SERIAL)
        return real(dirfd, t.to, st, flags);
    if (t.kind) {
        fill_stat(&t, st);
        return 0;
    }
    return real(dirfd, path, st, flags);
}

EXPORT int fstatat(int dirfd, const char *path, struct stat *st, int flags) { return fstatat_target(dirfd, path, st, flags, LOAD(fstatat)); }
EXPORT int fstatat64(int dirfd, const char *path, struct stat64 *st, int flags)
{
    return fstatat_target(dirfd, path, (struct stat *)st, flags, (fstatat_fn)LOAD(fstatat64));
}

EXPORT int statx(int dirfd, const char *path, int flags, unsigned int mask, struct statx *sx)
{
    struct target t = classify_abs(path);
    if (is_empty(path) && (flags & AT_EMPTY_PATH) && fake_of(dirfd))
        t = fake_of(dirfd)->t;
    if (t.kind == K_SERIAL)
        return LOAD(statx)(dirfd, t.to, flags, mask, sx);
    if (!t.kind)
        return LOAD(statx)(dirfd, path, flags, mask, sx);
    struct stat st;
    fill_stat(&t, &st);
    memset(sx, 0, sizeof *sx);
    sx->stx_mask = STATX_BASIC_STATS;
    sx->stx_mode = (uint16_t)st.st_mode;
    sx->stx_nlink = (uint32_t)st.st_nlink;
    sx->stx_uid = st.st_uid;
    sx->stx_gid = st.st_gid;
    sx->stx_ino = st.st_ino;
    sx->stx_size = (uint64_t)st.st_size;
    sx->stx_blksize = (uint32_t)st.st_blksize;
    sx->stx_rdev_major = major(st.st_rdev);
    sx->stx_rdev_minor = minor(st.st_rdev);
    return 0;
}

static int access_target(const struct target *t, int amode)
{
    struct stat st;
    fill_stat(t, &st);
    if (((amode & X_OK) && !S_ISDIR(st.st_mode)) || ((amode & W_OK) && !(st.st_mode & 0200)) ||
        ((amode & R_OK) && !(st.st_mode & 0444) && getuid() != 0)) {
        errno = EACCES;
        return -1;
    }
    return 0;
}

EXPORT int access(const char *path, int amode)
{
    struct target t = classify(path);
    if (t.kind == K_SERIAL)
        return LOAD(access)(t.to, amode);
    return t.kind ? access_target(&t, amode) : LOAD(access)(path, amode);
}

EXPORT int faccessat(int dirfd, const char *path, int amode, int flags)
{
    struct target t = classify_abs(path);
    if (t.kind == K_SERIAL)
        return LOAD(faccessat)(dirfd, t.to, amode, flags);
    return t.kind ? access_target(&t, amode) : LOAD(faccessat)(dirfd, path, amode, flags);
}

/* ---------------------------------------------------------------- I2C and PWM calls on descriptors */

EXPORT int ioctl(int fd, unsigned long req, ...)
{
    va_list ap;
    va_start(ap, req);
    unsigned long arg = va_arg(ap, unsigned long);
    va_end(ap);
    struct fake *f = fake_of(fd);
    if (f && f->t.kind == K_I2C)
        return i2c_ioctl(f, req, arg);
    if (f)
        return errno_ret(ENOTTY);
    catch_up(); /* FIONREAD on a pty looks at the outside world too */
    return LOAD(ioctl)(fd, req, arg);
}

static ssize_t fake_write(struct fake *f, const void *buf, size_t n)
{
    if (f->t.kind == K_I2C) {
        size_t k = n > MAX_XFER ? MAX_XFER : n;
        if (copy_in(xfer_buf, buf, k))
            return errno_ret(EFAULT);
        struct i2c_msg m = {(uint16_t)f->addr, (uint16_t)(f->tenbit ? I2C_M_TEN : 0), (uint16_t)k, xfer_buf};
        int err = i2c_transfer(f, &m, 1);
        return err ? errno_ret(err) : (ssize_t)k;
    }
    if (f->t.kind != K_PWM_ATTR)
        return errno_ret(EBADF);
    n = n > SYSFS_PAGE ? SYSFS_PAGE : n;
    if (copy_in(xfer_buf, buf, n))
        return errno_ret(EFAULT);
    const char *s = (const char *)xfer_buf;
    uint64_t v = 0;
    struct rig_pwm_msg msg = {.chip = (uint16_t)pwm_chip, .channel = (uint16_t)(f->t.channel < 0 ? 0 : f->t.channel)};
    pthread_mutex_lock(&lock);
    int err = 0;
    struct rig_pwm_state *p = f->t.channel >= 0 ? &shm->pwm[f->t.channel] : NULL;
    switch (f->t.attr) {
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
            *p = (struct rig_pwm_state){0}; /* unexport turns the output off */
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
        send_msg(RIG_MSG_PWM, &msg, sizeof msg); /* a notice: the DUT never waits for it */
    }
    pthread_mutex_unlock(&lock);
    return err ? errno_ret(err) : (ssize_t)n;
}

static ssize_t fake_read(struct fake *f, void *buf, size_t n, off_t *pos)
{
    if (f->t.kind == K_I2C) {
        size_t k = n > MAX_XFER ? MAX_XFER : n;
        struct i2c_msg m = {(uint16_t)f->addr, (uint16_t)(I2C_M_RD | (f->tenbit ? I2C_M_TEN : 0)), (uint16_t)k,
                            xfer_buf};
        int err = i2c_transfer(f, &m, 1);
        if (!err && copy_out(buf, xfer_buf, k))
            err = EFAULT; /* after the transfer, as i2c-dev's copy_to_user */
        return err ? errno_ret(err) : (ssize_t)k;
    }
    if (f->t.kind == K_PWM_DIR)
        return errno_ret(EISDIR);
    if (f->t.kind != K_PWM_ATTR)
        return errno_ret(EBADF);
    char text[32];
    struct rig_pwm_state *p = f->t.channel >= 0 ? &shm->pwm[f->t.channel] : NULL;
    switch (f->t.attr) {
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

EXPORT ssize_t read(int fd, void *buf, size_t n)
{
    struct fake *f = fake_of(fd);
    if (f)
        return fake_read(f, buf, n, &f->pos);
    catch_up();
    return LOAD(read)(fd, buf, n);
}

EXPORT ssize_t write(int fd, const void *buf, size_t n)
{
    struct fake *f = fake_of(fd);
    return f ? fake_write(f, buf, n) : LOAD(write)(fd, buf, n);
}

typedef ssize_t (*pread_fn)(int, void *, size_t, off_t);

static ssize_t pread_via(int fd, void *buf, size_t n, off_t off, pread_fn real)
{
    struct fake *f = fake_of(fd);
    if (f) /* i2c-dev has no offsets */
        return f->t.kind == K_I2C ? errno_ret(ESPIPE) : fake_read(f, buf, n, &off);
    catch_up();
    return real(fd, buf, n, off);
}

EXPORT ssize_t pread(int fd, void *buf, size_t n, off_t off) { return pread_via(fd, buf, n, off, LOAD(pread)); }
EXPORT ssize_t pread64(int fd, void *buf, size_t n, off_t off) { return pread_via(fd, buf, n, off, LOAD(pread64)); }

EXPORT ssize_t pwrite(int fd, const void *buf, size_t n, off_t off)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(pwrite)(fd, buf, n, off);
    return f->t.kind == K_I2C ? errno_ret(ESPIPE) : fake_write(f, buf, n);
}

EXPORT ssize_t pwrite64(int fd, const void *buf, size_t n, off_t off)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(pwrite64)(fd, buf, n, off);
    return f->t.kind == K_I2C ? errno_ret(ESPIPE) : fake_write(f, buf, n);
}

static off_t fake_seek(struct fake *f, off_t off, int whence)
{
    if (f->t.kind == K_I2C)
        return errno_ret(ESPIPE);
    off_t base = whence == SEEK_SET ? 0 : whence == SEEK_CUR ? f->pos : -1;
    if (base < 0 || base + off < 0)
        return errno_ret(EINVAL);
    f->pos = base + off;
    return f->pos;
}

EXPORT off_t lseek(int fd, off_t off, int whence)
{
    struct fake *f = fake_of(fd);
    return f ? fake_seek(f, off, whence) : LOAD(lseek)(fd, off, whence);
}

EXPORT off_t lseek64(int fd, off_t off, int whence)
{
    struct fake *f = fake_of(fd);
    return f ? fake_seek(f, off, whence) : LOAD(lseek64)(fd, off, whence);
}
