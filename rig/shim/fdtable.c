/*
 * Fake descriptors: the table of descriptors that are an emulated device's, the backing files that
 * make them real descriptors (numbers, dup, poll, exec), their adoption after exec, close, the dup
 * family and fcntl, and stdio on them (a cookie FILE from fopen; stdin, stdout and stderr swapped for
 * one while descriptor 0, 1 or 2 is a fake). Part of rigshim.c (one translation unit): see its top
 * comment.
 */

static char fakes_dir[PATH_MAX]; /* RIG_FAKES: the session's folder of backing files (see open_fake) */

struct fake {
    struct target t;
    int addr; /* I2C_SLAVE */
    int tenbit;
    off_t pos; /* PWM attribute read position */
};
static struct fake *fakes[MAX_FD];

static struct fake *fake_of(int fd) { return (active && fd >= 0 && fd < MAX_FD) ? fakes[fd] : NULL; }

static void std_sync(int fd);

/* The table's one writer: fd is now f (NULL: not a fake). Then stdin/stdout/stderr follow (std_sync).
   Not in a vfork child: the table and stdout it would change are its parent's, whose descriptors have
   not changed (the child's dup2 onto 1 before exec would make the parent's fd 1 a fake). What the child
   execs finds its fakes from /proc/self/fd. */
static int set_fake(int fd, struct fake *f)
{
    if (getpid() != own_pid) {
        free(f);
        return 0;
    }
    LOAD(pthread_mutex_lock)(&lock);
    free(fakes[fd]);
    fakes[fd] = f;
    pthread_mutex_unlock(&lock);
    std_sync(fd);
    return 1;
}

/* A fake descriptor is a real one onto a file of its own in the session's folder (RIG_FAKES), named
   after the target's path with ':' for '/': its number is unique, close, dup, fcntl and poll work on
   it, and it says what it is across exec, where this table is lost: a shell opens the attribute and
   dup2s it onto 1, then execs echo, whose shim finds the fake again from /proc/self/fd
   (adopt_inherited_fakes). The file keeps the access mode asked for. The shim never writes to it:
   bytes there came through a call it cannot see (a raw syscall, pwritev), and the session
   reports them. Without RIG_FAKES (an older session) the descriptor is onto /dev/null. */
static void backing_name(const struct target *t, char *buf, size_t n)
{
    kinds[t->kind].name(t, buf, n);
    for (char *c = buf; *c; c++)
        if (*c == '/')
            *c = ':';
}

static int backing_open(const struct target *t, int flags)
{
    if (!fakes_dir[0])
        return LOAD(open)("/dev/null", O_RDWR | (flags & O_CLOEXEC));
    char path[PATH_MAX + 128], name[128];
    backing_name(t, name, sizeof name);
    snprintf(path, sizeof path, "%s/%s", fakes_dir, name);
    return LOAD(open)(path, (flags & (O_ACCMODE | O_CLOEXEC | O_NONBLOCK)) | O_CREAT, 0600);
}

/* A new fake descriptor onto t, once its kind has accepted the flags (the kind's open, or dispatch.c's
   generic answer). */
static int open_fake(const struct target *t, int flags)
{
    int fd = backing_open(t, flags);
    if (fd < 0)
        return -1;
    if (fd >= MAX_FD) {
        LOAD(close)(fd);
        errno = EMFILE;
        return -1;
    }
    struct fake *f = calloc(1, sizeof *f);
    if (!f) {
        LOAD(close)(fd);
        errno = ENOMEM;
        return -1;
    }
    f->t = *t;
    f->addr = 0; /* i2c-dev's client starts at address 0, where nothing answers */
    if (set_fake(fd, f)) {
        /* Opening an emulated device is touching the devices, even when all that follows is a read or
           a write the kernel refuses (neither sends anything): connect, so the session knows. */
        LOAD(pthread_mutex_lock)(&lock);
        ensure_connected();
        pthread_mutex_unlock(&lock);
    }
    return fd;
}

static void drop_fake(int fd)
{
    if (fd >= 0 && fd < MAX_FD && fakes[fd])
        set_fake(fd, NULL);
}

/* `to` is now a copy of `from` (dup and friends): a fake's copy is a fake, anything else's is not. */
static void copy_fake(int from, int to)
{
    if (to < 0 || to >= MAX_FD)
        return;
    struct fake *src = fake_of(from), *f = NULL;
    if (src && (f = malloc(sizeof *f)))
        *f = *src;
    if (f || fakes[to])
        set_fake(to, f);
}

/* At start-up (after exec): the descriptors onto files in RIG_FAKES are fakes this process inherited.
   An I2C client's address and a read position start afresh (they live in the table, not the file). */
static void adopt_inherited_fakes(void)
{
    if (!fakes_dir[0])
        return;
    int dfd = LOAD(open)("/proc/self/fd", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0)
        return;
    size_t plen = strlen(fakes_dir);
    char buf[4096], link[PATH_MAX];
    long n;
    while ((n = syscall(SYS_getdents64, dfd, buf, sizeof buf)) > 0) {
        for (long off = 0; off < n;) {
            struct dirent64 *d = (struct dirent64 *)(buf + off);
            off += d->d_reclen;
            const char *end;
            int fd = parse_uint(d->d_name, &end);
            if (fd < 0 || *end || fd == dfd || fd >= MAX_FD)
                continue;
            ssize_t k = readlinkat(dfd, d->d_name, link, sizeof link - 1);
            if (k <= (ssize_t)plen + 1 || memcmp(link, fakes_dir, plen) != 0 || link[plen] != '/')
                continue;
            link[k] = 0;
            char *name = link + plen + 1;
            for (char *c = name; *c; c++)
                if (*c == ':')
                    *c = '/';
            struct target t = classify_path(name, 1);
            struct fake *f = t.kind && kinds[t.kind].name ? calloc(1, sizeof *f) : NULL; /* a kind with fakes */
            if (f) {
                f->t = t;
                set_fake(fd, f);
            }
        }
    }
    LOAD(close)(dfd);
}

static ssize_t fake_read(struct fake *f, void *buf, size_t n, off_t *pos);
static ssize_t fake_write(struct fake *f, const void *buf, size_t n);

/* stdio on a PWM attribute: glibc's fopen and fwrite use internal calls we cannot interpose, so the
   FILE gets our read/write through fopencookie. */
static ssize_t cookie_read(void *c, char *buf, size_t n)
{
    struct fake *f = fake_of((int)(intptr_t)c);
    return f ? fake_read(f, buf, n, &f->pos) : -1;
}
static ssize_t cookie_write(void *c, const char *buf, size_t n)
{
    struct fake *f = fake_of((int)(intptr_t)c);
    ssize_t r = f ? fake_write(f, buf, n) : -1;
    return r < 0 ? 0 : r; /* stdio treats a short write as the error */
}
static int cookie_seek(void *c, off64_t *off, int whence)
{
    struct fake *f = fake_of((int)(intptr_t)c);
    if (!f || whence != SEEK_SET || *off < 0)
        return -1;
    f->pos = *off;
    return 0;
}
static int cookie_close(void *c) { return close((int)(intptr_t)c); }

/* A stream on fake descriptor fd (fopen's, fdopen's): its reads and writes reach the device, and
   fclose closes fd. */
static FILE *fake_stream(int fd, const char *mode)
{
    cookie_io_functions_t io = { cookie_read, cookie_write, cookie_seek, cookie_close };
    return fopencookie((void *)(intptr_t)fd, mode, io);
}

EXPORT int close(int fd)
{
    if (active && fd == sock && sock_pid == self_pid())
        return 0; /* a program closing every descriptor must not cut us off from the session */
    drop_fake(fd);
    timer_closed(fd);
    return LOAD(close)(fd);
}

EXPORT int dup(int fd)
{
    int r = LOAD(dup)(fd);
    if (r >= 0)
        copy_fake(fd, r);
    return r;
}

EXPORT int dup2(int fd, int to)
{
    int r = LOAD(dup2)(fd, to);
    if (r >= 0 && fd != to)
        copy_fake(fd, r);
    return r;
}

EXPORT int dup3(int fd, int to, int flags)
{
    int r = LOAD(dup3)(fd, to, flags);
    if (r >= 0)
        copy_fake(fd, r);
    return r;
}

/* fcntl's F_DUPFD and F_DUPFD_CLOEXEC are dups too: shells save a descriptor they redirect that way
   (dash: fcntl(1, F_DUPFD_CLOEXEC, 10)) and dup2 it back afterwards. Programs built with 64-bit file
   offsets call fcntl64. The argument is an int or a pointer: passed on as it came. */
static int fcntl_via(int fd, int cmd, void *arg, int (*real)(int, int, ...))
{
    int r = real(fd, cmd, arg);
    if (r >= 0 && (cmd == F_DUPFD || cmd == F_DUPFD_CLOEXEC))
        copy_fake(fd, r);
    return r;
}

EXPORT int fcntl(int fd, int cmd, ...)
{
    va_list ap;
    va_start(ap, cmd);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    return fcntl_via(fd, cmd, arg, LOAD(fcntl));
}

EXPORT int fcntl64(int fd, int cmd, ...)
{
    va_list ap;
    va_start(ap, cmd);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    return fcntl_via(fd, cmd, arg, LOAD(fcntl64));
}

static off_t fake_seek(struct fake *f, off_t off, int whence);

/* ---------------------------------------------------------------- stdin, stdout, stderr on a fake */

/* glibc's stdio writes a FILE's buffer with an internal write() no preload can redirect. So bash's
   echo and printf (builtins printing on stdout after the shell dup2'd the attribute onto descriptor 1)
   and coreutils' echo (exec'd with it) would write to the backing file and report success. While
   descriptor 0, 1 or 2 is a fake, stdin/stdout/stderr is a cookie stream that goes through the shim
   (whose errors reach the caller: bash says "echo: write error: No such device"); when it stops being
   one, the program's own FILE is back. The swap keeps what a FILE would: pending output moves with
   it (a FILE writes what it holds to whatever its descriptor is at flush time), so do the error and
   end-of-file flags, and fileno() still answers 0, 1 or 2. A cookie is made once per descriptor and
   kept (the program may still hold its pointer), and writes to the real descriptor when that is not a
   fake. The program's fclose(stdout) closes the descriptor, as its own FILE would. */
struct std_stream {
    FILE *orig; /* the program's FILE, while swapped */
    FILE *cookie;
    int swapped;
};
static struct std_stream stds[3];
static pthread_mutex_t std_lock = PTHREAD_MUTEX_INITIALIZER;
static void reset_std_lock(void) { pthread_mutex_init(&std_lock, NULL); }

static FILE **std_var(int fd) { return fd == 0 ? &stdin : fd == 1 ? &stdout : &stderr; }

static ssize_t std_read(void *c, char *buf, size_t n)
{
    int fd = (int)(intptr_t)c;
    struct fake *f = fake_of(fd);
    return f ? fake_read(f, buf, n, &f->pos) : LOAD(read)(fd, buf, n);
}

static ssize_t std_write(void *c, const char *buf, size_t n)
{
    int fd = (int)(intptr_t)c;
    struct fake *f = fake_of(fd);
    if (f) {
        ssize_t r = fake_write(f, buf, n);
        return r < 0 ? 0 : r; /* stdio takes a short write as the error; errno says which */
    }
    size_t done = 0;
    while (done < n) {
        ssize_t k = LOAD(write)(fd, buf + done, n - done);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            break;
        done += (size_t)k;
    }
    return (ssize_t)done;
}

static int std_seek(void *c, off64_t *off, int whence)
{
    int fd = (int)(intptr_t)c;
    struct fake *f = fake_of(fd);
    off_t r = f ? fake_seek(f, *off, whence) : LOAD(lseek)(fd, *off, whence);
    if (r < 0)
        return -1;
    *off = r;
    return 0;
}

static int std_close(void *c)
{
    int fd = (int)(intptr_t)c;
    struct std_stream *s = &stds[fd];
    if (*std_var(fd) == s->cookie)
        *std_var(fd) = s->orig;
    s->cookie = NULL; /* fclose frees it */
    s->swapped = 0;
    return close(fd);
}

static FILE *std_cookie(int fd, FILE *like)
{
    cookie_io_functions_t io = { std_read, std_write, std_seek, std_close };
    FILE *fp = fopencookie((void *)(intptr_t)fd, fd == 0 ? "r" : "w", io);
    if (!fp)
        return NULL;
    fp->_fileno = fd; /* glibc marks a cookie stream -2; any other number it leaves to fileno() */
    if (fd == 2)
        setvbuf(fp, NULL, _IONBF, 0);
    else if (fd == 1 && __flbf(like))
        setvbuf(fp, NULL, _IOLBF, BUFSIZ);
    return fp;
}

static void move_stream(FILE *from, FILE *to)
{
    size_t k = __fpending(from);
    if (k && fwide(from, 0) <= 0) {
        fwrite(from->_IO_write_base, 1, k, to);
        __fpurge(from);
    }
    int flags = from->_flags & (_IO_ERR_SEEN | _IO_EOF_SEEN);
    to->_flags = (to->_flags & ~(_IO_ERR_SEEN | _IO_EOF_SEEN)) | flags;
}

static void std_sync(int fd)
{
    if (fd < 0 || fd > 2 || (fake_of(fd) != NULL) == stds[fd].swapped)
        return;
    struct std_stream *s = &stds[fd];
    FILE **var = std_var(fd);
    LOAD(pthread_mutex_lock)(&std_lock);
    if (fake_of(fd) && !s->swapped) {
        FILE *cur = *var; /* only the stream that is on this descriptor (a program may point stdout elsewhere) */
        if (cur && cur != s->cookie && fileno(cur) == fd && (s->cookie || (s->cookie = std_cookie(fd, cur)))) {
            move_stream(cur, s->cookie);
            s->orig = cur;
            *var = s->cookie;
            s->swapped = 1;
        }
    } else if (!fake_of(fd) && s->swapped) {
        s->swapped = 0;
        if (*var == s->cookie) {
            move_stream(s->cookie, s->orig);
            *var = s->orig;
        } else {
            fflush(s->cookie);
        }
    }
    pthread_mutex_unlock(&std_lock);
}
