/*
 * The interposed calls that may be a device's: on a path (open and friends, fopen, opendir, the stat
 * family, access) or on a descriptor (read, write, pread, pwrite, lseek, ioctl, fstat, fdopendir, the
 * copies between descriptors). Each classifies the path or looks the descriptor up in the table, then
 * calls the kind's operation in kinds[] (rigshim.c) or, where the kind has none, gives the generic
 * answer written here, the one for a device file the shim emulates behind a fake descriptor. No call
 * here tests a kind. Part of rigshim.c (one translation unit): see its top comment.
 */

/* ---------------------------------------------------------------- calls on fake descriptors */

/* read and write: the kind's, else EBADF (a descriptor the kind cannot read or write). */
static ssize_t fake_read(struct fake *f, void *buf, size_t n, off_t *pos)
{
    const struct kind_ops *k = &kinds[f->t.kind];
    return k->read ? k->read(f, buf, n, pos) : errno_ret(EBADF);
}

static ssize_t fake_write(struct fake *f, const void *buf, size_t n)
{
    const struct kind_ops *k = &kinds[f->t.kind];
    return k->write ? k->write(f, buf, n) : errno_ret(EBADF);
}

/* lseek: the kind's, else the read position moves (SEEK_SET and SEEK_CUR, as sysfs allows). */
static off_t fake_seek(struct fake *f, off_t off, int whence)
{
    const struct kind_ops *k = &kinds[f->t.kind];
    if (k->seek)
        return k->seek(f, off, whence);
    off_t base = whence == SEEK_SET ? 0 : whence == SEEK_CUR ? f->pos : -1;
    if (base < 0 || base + off < 0)
        return errno_ret(EINVAL);
    f->pos = base + off;
    return f->pos;
}

EXPORT ssize_t read(int fd, void *buf, size_t n)
{
    struct fake *f = fake_of(fd);
    if (f)
        return fake_read(f, buf, n, &f->pos);
    struct vtimer *t = vtimer_of(fd);
    if (t)
        return timer_read(t, buf, n);
    catch_up();
    return LOAD(read)(fd, buf, n);
}

EXPORT ssize_t write(int fd, const void *buf, size_t n)
{
    struct fake *f = fake_of(fd);
    return f ? fake_write(f, buf, n) : LOAD(write)(fd, buf, n);
}

/* pread and pwrite: the kind's, else a read at the offset (the descriptor's position unchanged) and a
   plain write (a sysfs attribute takes no offset). */
typedef ssize_t (*pread_fn)(int, void *, size_t, off_t);

static ssize_t pread_via(int fd, void *buf, size_t n, off_t off, pread_fn real)
{
    struct fake *f = fake_of(fd);
    if (f) {
        const struct kind_ops *k = &kinds[f->t.kind];
        return k->pread ? k->pread(f, buf, n, off) : fake_read(f, buf, n, &off);
    }
    catch_up();
    return real(fd, buf, n, off);
}

EXPORT ssize_t pread(int fd, void *buf, size_t n, off_t off) { return pread_via(fd, buf, n, off, LOAD(pread)); }
EXPORT ssize_t pread64(int fd, void *buf, size_t n, off_t off) { return pread_via(fd, buf, n, off, LOAD(pread64)); }

static ssize_t fake_pwrite(struct fake *f, const void *buf, size_t n, off_t off)
{
    const struct kind_ops *k = &kinds[f->t.kind];
    return k->pwrite ? k->pwrite(f, buf, n, off) : fake_write(f, buf, n);
}

EXPORT ssize_t pwrite(int fd, const void *buf, size_t n, off_t off)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(pwrite)(fd, buf, n, off);
    return fake_pwrite(f, buf, n, off);
}

EXPORT ssize_t pwrite64(int fd, const void *buf, size_t n, off_t off)
{
    struct fake *f = fake_of(fd);
    if (!f)
        return LOAD(pwrite64)(fd, buf, n, off);
    return fake_pwrite(f, buf, n, off);
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

/* ioctl: the kind's, else ENOTTY (a device with no requests of its own). */
EXPORT int ioctl(int fd, unsigned long req, ...)
{
    va_list ap;
    va_start(ap, req);
    unsigned long arg = va_arg(ap, unsigned long);
    va_end(ap);
    struct fake *f = fake_of(fd);
    if (f)
        return kinds[f->t.kind].ioctl ? kinds[f->t.kind].ioctl(f, req, arg) : errno_ret(ENOTTY);
    catch_up(); /* FIONREAD on a pty looks at the outside world too */
    return LOAD(ioctl)(fd, req, arg);
}

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
   page per call, through the shim's read and write. A kind that cannot splice (i2c-dev): EINVAL. */
static ssize_t sendfile_fake(int out, int in, off64_t *off, size_t count)
{
    struct fake *fi = fake_of(in), *fo = fake_of(out);
    if ((fi && !kinds[fi->t.kind].sendfile) || (fo && !kinds[fo->t.kind].sendfile))
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

/* ---------------------------------------------------------------- writes through libc's other doors */

/* writev: the iovec array copied in as the kernel copies it (EINVAL for a count outside 0..IOV_MAX,
   EFAULT for an array it cannot read); then the kind's gather decides: one write of the pieces joined
   (sysfs: a page at most, as kernfs's write_iter), or one write per piece up to the first short or
   failed one (the VFS's loop for a driver with only .write, i2c-dev: each piece its own message). */
#define IOV_LIMIT 1024 /* UIO_MAXIOV */
static ssize_t fake_writev(struct fake *f, const struct iovec *uiov, int n)
{
    static __thread struct iovec iov[IOV_LIMIT];
    if (n < 0 || n > IOV_LIMIT)
        return errno_ret(EINVAL);
    if (n && copy_in(iov, uiov, (size_t)n * sizeof *iov))
        return errno_ret(EFAULT);
    if (kinds[f->t.kind].gather) {
        char joined[SYSFS_PAGE];
        size_t len = 0;
        for (int i = 0; i < n && len < sizeof joined; i++) {
            size_t k = iov[i].iov_len < sizeof joined - len ? iov[i].iov_len : sizeof joined - len;
            if (k && copy_in(joined + len, iov[i].iov_base, k))
                return errno_ret(EFAULT);
            len += k;
        }
        return fake_write(f, joined, len);
    }
    ssize_t total = 0;
    for (int i = 0; i < n; i++) {
        if (!iov[i].iov_len)
            continue;
        ssize_t k = fake_write(f, iov[i].iov_base, iov[i].iov_len);
        if (k < 0)
            return total ? total : -1;
        total += k;
        if ((size_t)k < iov[i].iov_len)
            break;
    }
    return total;
}

EXPORT ssize_t writev(int fd, const struct iovec *iov, int n)
{
    struct fake *f = fake_of(fd);
    return f ? fake_writev(f, iov, n) : LOAD(writev)(fd, iov, n);
}

/* dprintf and vdprintf (and their fortified forms): the text formatted, then written as glibc's
   vdprintf writes it (whole, again after a short write); -1 with the device's errno on an error. */
static int fake_vdprintf(struct fake *f, const char *fmt, va_list ap)
{
    char small[256], *text = small;
    va_list again;
    va_copy(again, ap);
    int n = vsnprintf(small, sizeof small, fmt, ap);
    if (n >= (int)sizeof small && vasprintf(&text, fmt, again) < 0)
        n = -1;
    va_end(again);
    for (int done = 0; n >= 0 && done < n;) {
        ssize_t k = fake_write(f, text + done, (size_t)(n - done));
        if (k <= 0)
            n = -1;
        else
            done += (int)k;
    }
    if (text != small) {
        int saved = errno;
        free(text);
        errno = saved;
    }
    return n;
}

EXPORT int vdprintf(int fd, const char *fmt, va_list ap)
{
    struct fake *f = fake_of(fd);
    return f ? fake_vdprintf(f, fmt, ap) : LOAD(vdprintf)(fd, fmt, ap);
}

EXPORT int dprintf(int fd, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vdprintf(fd, fmt, ap);
    va_end(ap);
    return n;
}

EXPORT int __vdprintf_chk(int fd, int flag, const char *fmt, va_list ap)
{
    struct fake *f = fake_of(fd);
    return f ? fake_vdprintf(f, fmt, ap) : LOAD(__vdprintf_chk)(fd, flag, fmt, ap);
}

EXPORT int __dprintf_chk(int fd, int flag, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = __vdprintf_chk(fd, flag, fmt, ap);
    va_end(ap);
    return n;
}

/* fdopen on a fake descriptor: a stream through the shim (fake_stream), refused as glibc refuses a mode
   the descriptor's access mode does not allow (EINVAL). */
EXPORT FILE *fdopen(int fd, const char *mode)
{
    if (!fake_of(fd))
        return LOAD(fdopen)(fd, mode);
    int acc = LOAD(fcntl)(fd, F_GETFL) & O_ACCMODE;
    int wants_read = mode[0] == 'r' || strchr(mode, '+'), wants_write = mode[0] != 'r' || strchr(mode, '+');
    if ((wants_read && acc == O_WRONLY) || (wants_write && acc == O_RDONLY)) {
        errno = EINVAL;
        return NULL;
    }
    return fake_stream(fd, mode);
}

/* ---------------------------------------------------------------- open and fopen */

#define OPEN_MODE(flags, mode)                   \
    do {                                         \
        if ((flags) & (O_CREAT | __O_TMPFILE)) { \
            va_list ap;                          \
            va_start(ap, flags);                 \
            mode = va_arg(ap, mode_t);           \
            va_end(ap);                          \
        }                                        \
    } while (0)

/* open: the kind's, else a fake descriptor (ENOTDIR with O_DIRECTORY: a device file is no directory). */
static int kind_open(const struct target *t, int flags, mode_t mode)
{
    const struct kind_ops *k = &kinds[t->kind];
    if (k->open)
        return k->open(t, flags, mode);
    if (flags & O_DIRECTORY)
        return errno_ret(ENOTDIR);
    return open_fake(t, flags);
}

EXPORT int open(const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify(path);
    return t.kind ? kind_open(&t, flags, mode) : LOAD(open)(path, flags, mode);
}

EXPORT int open64(const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify(path);
    return t.kind ? kind_open(&t, flags, mode) : LOAD(open64)(path, flags, mode);
}

EXPORT int openat(int dirfd, const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify_abs(path);
    return t.kind ? kind_open(&t, flags, mode) : LOAD(openat)(dirfd, path, flags, mode);
}

EXPORT int openat64(int dirfd, const char *path, int flags, ...)
{
    mode_t mode = 0;
    OPEN_MODE(flags, mode);
    struct target t = classify_abs(path);
    return t.kind ? kind_open(&t, flags, mode) : LOAD(openat64)(dirfd, path, flags, mode);
}

EXPORT int __open_2(const char *path, int flags)
{
    struct target t = classify(path);
    return t.kind ? kind_open(&t, flags, 0) : LOAD(__open_2)(path, flags);
}

EXPORT int __open64_2(const char *path, int flags)
{
    struct target t = classify(path);
    return t.kind ? kind_open(&t, flags, 0) : LOAD(__open64_2)(path, flags);
}

EXPORT int __openat_2(int dirfd, const char *path, int flags)
{
    struct target t = classify_abs(path);
    return t.kind ? kind_open(&t, flags, 0) : LOAD(__openat_2)(dirfd, path, flags);
}

EXPORT int __openat64_2(int dirfd, const char *path, int flags)
{
    struct target t = classify_abs(path);
    return t.kind ? kind_open(&t, flags, 0) : LOAD(__openat64_2)(dirfd, path, flags);
}

/* fopen: the kind's, else a cookie stream (fdtable.c) over a descriptor opened as open would. */
static FILE *kind_fopen(const char *path, const struct target *t, const char *mode, fopen_fn real)
{
    if (kinds[t->kind].fopen)
        return kinds[t->kind].fopen(path, t, mode, real);
    int flags = strchr(mode, '+') ? O_RDWR : mode[0] == 'r' ? O_RDONLY : O_WRONLY;
    if (strchr(mode, 'e'))
        flags |= O_CLOEXEC;
    int fd = kind_open(t, flags, 0);
    if (fd < 0)
        return NULL;
    FILE *fp = fake_stream(fd, mode);
    if (!fp)
        close(fd);
    return fp;
}

EXPORT FILE *fopen(const char *path, const char *mode)
{
    struct target t = classify(path);
    return t.kind ? kind_fopen(path, &t, mode, LOAD(fopen)) : LOAD(fopen)(path, mode);
}

EXPORT FILE *fopen64(const char *path, const char *mode)
{
    struct target t = classify(path);
    return t.kind ? kind_fopen(path, &t, mode, LOAD(fopen64)) : LOAD(fopen64)(path, mode);
}

/* ---------------------------------------------------------------- directories */

/* opendir: the kind's, else a stream of the kind's dir_entry (fakedir.c) on a descriptor opened as open
   would, or ENOTDIR for a kind that lists nothing. fdopendir likewise on a fake descriptor. */
EXPORT DIR *opendir(const char *path)
{
    struct target t = classify(path);
    if (!t.kind)
        return LOAD(opendir)(path);
    const struct kind_ops *k = &kinds[t.kind];
    if (k->opendir)
        return k->opendir(path, &t);
    if (!k->dir_entry) {
        errno = ENOTDIR;
        return NULL;
    }
    int fd = kind_open(&t, O_RDONLY | O_DIRECTORY | O_CLOEXEC, 0);
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
    if (!kinds[f->t.kind].dir_entry) {
        errno = ENOTDIR;
        return NULL;
    }
    return dir_open(fd, &f->t);
}

/* ---------------------------------------------------------------- stat and access */

/* The stat family: the kind's, else what the kind's fill_stat shows. */
static int stat_target(const char *path, struct stat *st, stat_fn real)
{
    struct target t = classify(path);
    if (!t.kind)
        return real(path, st);
    const struct kind_ops *k = &kinds[t.kind];
    if (k->stat)
        return k->stat(&t, st, real);
    k->fill_stat(&t, st);
    return 0;
}

/* struct stat64 is struct stat on the 64-bit targets we build for; the casts below rely on it. */
_Static_assert(sizeof(struct stat) == sizeof(struct stat64), "struct stat64 differs from struct stat");
_Static_assert(sizeof(off_t) == sizeof(off64_t), "off64_t differs from off_t");

EXPORT int stat(const char *path, struct stat *st) { return stat_target(path, st, LOAD(stat)); }
EXPORT int stat64(const char *path, struct stat64 *st)
{
    return stat_target(path, (struct stat *)st, (stat_fn)LOAD(stat64));
}
EXPORT int lstat(const char *path, struct stat *st) { return stat_target(path, st, LOAD(lstat)); }
EXPORT int lstat64(const char *path, struct stat64 *st)
{
    return stat_target(path, (struct stat *)st, (stat_fn)LOAD(lstat64));
}

static int fstat_fake(int fd, struct stat *st, fstat_fn real)
{
    struct fake *f = fake_of(fd);
    if (f) {
        kinds[f->t.kind].fill_stat(&f->t, st);
        return 0;
    }
    return real(fd, st);
}

EXPORT int fstat(int fd, struct stat *st) { return fstat_fake(fd, st, LOAD(fstat)); }
EXPORT int fstat64(int fd, struct stat64 *st) { return fstat_fake(fd, (struct stat *)st, (fstat_fn)LOAD(fstat64)); }

static int fstatat_target(int dirfd, const char *path, struct stat *st, int flags, fstatat_fn real)
{
    if (is_empty(path) && (flags & AT_EMPTY_PATH)) {
        struct fake *f = fake_of(dirfd);
        return f ? (kinds[f->t.kind].fill_stat(&f->t, st), 0) : real(dirfd, path, st, flags);
    }
    struct target t = classify_abs(path);
    if (!t.kind)
        return real(dirfd, path, st, flags);
    const struct kind_ops *k = &kinds[t.kind];
    if (k->fstatat)
        return k->fstatat(dirfd, &t, st, flags, real);
    k->fill_stat(&t, st);
    return 0;
}

EXPORT int fstatat(int dirfd, const char *path, struct stat *st, int flags)
{
    return fstatat_target(dirfd, path, st, flags, LOAD(fstatat));
}
EXPORT int fstatat64(int dirfd, const char *path, struct stat64 *st, int flags)
{
    return fstatat_target(dirfd, path, (struct stat *)st, flags, (fstatat_fn)LOAD(fstatat64));
}

EXPORT int statx(int dirfd, const char *path, int flags, unsigned int mask, struct statx *sx)
{
    struct target t = classify_abs(path);
    if (is_empty(path) && (flags & AT_EMPTY_PATH) && fake_of(dirfd))
        t = fake_of(dirfd)->t;
    if (!t.kind)
        return LOAD(statx)(dirfd, path, flags, mask, sx);
    const struct kind_ops *k = &kinds[t.kind];
    if (k->statx)
        return k->statx(dirfd, &t, flags, mask, sx);
    struct stat st;
    k->fill_stat(&t, &st);
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

/* access and faccessat: the kind's, else by the mode fill_stat shows (root reads anything). */
static int access_target(const struct target *t, int amode)
{
    struct stat st;
    kinds[t->kind].fill_stat(t, &st);
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
    if (!t.kind)
        return LOAD(access)(path, amode);
    return kinds[t.kind].access ? kinds[t.kind].access(&t, amode) : access_target(&t, amode);
}

EXPORT int faccessat(int dirfd, const char *path, int amode, int flags)
{
    struct target t = classify_abs(path);
    if (!t.kind)
        return LOAD(faccessat)(dirfd, path, amode, flags);
    const struct kind_ops *k = &kinds[t.kind];
    return k->faccessat ? k->faccessat(dirfd, &t, amode, flags) : access_target(&t, amode);
}
