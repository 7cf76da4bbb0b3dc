/*
 * What a path names, and the shape of a device kind. classify turns a path into a target (a device of
 * one of the kinds, or nothing of ours) by asking each kind in turn; a kind's operations (struct
 * kind_ops) are what every interposer calls for a path or a descriptor of that kind, so the
 * interposers (dispatch.c) never test kinds. Part of rigshim.c (one translation unit): see its top
 * comment.
 */

/* What a path names: its kind and, for the kind, which of its files (the fields a kind does not use
   stay 0). */
struct target {
    enum kind kind;
    int bus;        /* I2C: the bus */
    int channel;    /* PWM: the channel, -1 for the chip itself, -2 for /sys/class/pwm, -3 for its .. */
    int attr;       /* PWM attributes: which (enum pwm_attr) */
    const char *to; /* serial: the pty */
};

struct fake; /* a fake descriptor (fdtable.c) */

typedef int (*stat_fn)(const char *, struct stat *);
typedef int (*fstat_fn)(int, struct stat *);
typedef int (*fstatat_fn)(int, const char *, struct stat *, int);
typedef FILE *(*fopen_fn)(const char *, const char *);

/* A device kind's operations, one row of kinds[] (rigshim.c). An operation left NULL gets the generic
   answer, the one for a device file the shim emulates behind a fake descriptor (dispatch.c); the
   comment after each says what that is. */
struct kind_ops {
    /* claim classifies a path: 1 when the path is the kind's to decide (t->kind left K_NONE when it
       names nothing emulated), 0 to let the next kind look; inherited: see classify_path. NULL when
       another row of the same file claims for this kind too. init reads the kind's configuration from
       the environment at start-up. */
    int (*claim)(const char *path, int inherited, struct target *t);
    void (*init)(void);
    /* For a kind with fake descriptors: name writes the kernel's path of a target (its backing file is
       named after it), fill_stat what stat shows. NULL name: the kind makes no fake descriptors. */
    void (*name)(const struct target *t, char *buf, size_t n);
    void (*fill_stat)(const struct target *t, struct stat *st);

    /* calls on a path */
    int (*open)(const struct target *t, int flags, mode_t mode); /* a fake; O_DIRECTORY: ENOTDIR */
    FILE *(*fopen)(const char *path, const struct target *t, const char *mode, fopen_fn real);
    /* a stream through the fake */
    DIR *(*opendir)(const char *path, const struct target *t);          /* dir_entry's stream, or ENOTDIR */
    int (*stat)(const struct target *t, struct stat *st, stat_fn real); /* stat, lstat: fill_stat */
    int (*fstatat)(int dirfd, const struct target *t, struct stat *st, int flags, fstatat_fn real);
    /* fill_stat */
    int (*statx)(int dirfd, const struct target *t, int flags, unsigned int mask, struct statx *sx);
    /* fill_stat's fields */
    int (*access)(const struct target *t, int amode);                          /* by fill_stat's mode */
    int (*faccessat)(int dirfd, const struct target *t, int amode, int flags); /* as access */

    /* calls on a fake descriptor */
    ssize_t (*read)(struct fake *f, void *buf, size_t n, off_t *pos);        /* EBADF */
    ssize_t (*write)(struct fake *f, const void *buf, size_t n);             /* EBADF */
    ssize_t (*pread)(struct fake *f, void *buf, size_t n, off_t off);        /* read at off */
    ssize_t (*pwrite)(struct fake *f, const void *buf, size_t n, off_t off); /* write, off unused */
    off_t (*seek)(struct fake *f, off_t off, int whence);                    /* moves the read position */
    int (*ioctl)(struct fake *f, unsigned long req, unsigned long arg);      /* ENOTTY */
    int sendfile; /* 1: sendfile copies to and from it through read and write (0: EINVAL, as i2c-dev) */
    int gather;   /* 1: writev is one write of its pieces joined (kernfs's write_iter, a page at most);
                     0: one write per piece, as the VFS does for a driver with only .write (i2c-dev) */

    /* A directory's listing: the state it starts from, taken when a stream opens or rewinds, and its
       entry i in that state (0: past the end). NULL dir_entry: not a directory. */
    uint32_t (*dir_start)(const struct target *dir);
    int (*dir_entry)(const struct target *dir, uint32_t start, long i, struct dirent64 *e);
};

static const struct kind_ops kinds[N_KINDS]; /* the rows: rigshim.c, after the kinds' files */

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

/* What a path names: the first kind that claims it decides, in the order of enum kind. inherited: a
   descriptor inherited across exec names this path, and its file exists even if a path alone would
   not (a pwmN the program has unexported since, as an open file outlives its name). */
static struct target classify_path(const char *path, int inherited)
{
    struct target t = { .kind = K_NONE };
    if (!active || !path)
        return t;
    for (int k = K_NONE + 1; k < N_KINDS; k++)
        if (kinds[k].claim && kinds[k].claim(path, inherited, &t))
            break;
    return t;
}

static struct target classify(const char *path) { return classify_path(path, 0); }

/* Only absolute paths are redirected (openat with a directory and a relative path passes through). */
static struct target classify_abs(const char *path)
{
    return path && path[0] == '/' ? classify(path) : (struct target){ .kind = K_NONE };
}

static int is_empty(const char *path) { return path && path[0] == 0; }

/* What stat shows of every file the shim pretends (a path the kernel would have: ENOENT-proof for stat
   and access); the kind's fill_stat adds the type, the mode and the rest. */
static void stat_common(struct stat *st, ino_t ino)
{
    memset(st, 0, sizeof *st);
    st->st_uid = getuid();
    st->st_gid = getgid();
    st->st_nlink = 1;
    st->st_blksize = 4096;
    st->st_ino = ino;
}
