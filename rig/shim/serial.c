/*
 * The device kind K_SERIAL: chosen serial paths (RIG_SERIAL="/dev/ttyRC0=/dev/pts/5:...") are the
 * slave side of a pty the session owns. Nothing here is emulated: a call on such a path goes to libc
 * with the pty's path instead, so the descriptor is the pty's own and the calls on it pass through.
 * Its row in kinds[] (rigshim.c) names the operations. Part of rigshim.c (one translation unit): see
 * its top comment.
 */

#define MAX_SERIAL 8

static struct {
    char from[128];
    char to[128];
} serial_map[MAX_SERIAL];
static int n_serial;

static void parse_serial(const char *spec)
{
    while (spec && *spec && n_serial < MAX_SERIAL) {
        const char *end = strchr(spec, ':');
        size_t n = end ? (size_t)(end - spec) : strlen(spec);
        const char *eq = memchr(spec, '=', n);
        if (eq && (size_t)(eq - spec) < sizeof serial_map[0].from &&
            n - (size_t)(eq - spec) - 1 < sizeof serial_map[0].to) {
            memcpy(serial_map[n_serial].from, spec, (size_t)(eq - spec));
            memcpy(serial_map[n_serial].to, eq + 1, n - (size_t)(eq - spec) - 1);
            n_serial++;
        }
        spec = end ? end + 1 : NULL;
    }
}

static void serial_init(void) { parse_serial(getenv("RIG_SERIAL")); }

static int serial_claim(const char *path, int inherited, struct target *t)
{
    (void)inherited;
    for (int i = 0; i < n_serial; i++)
        if (strcmp(path, serial_map[i].from) == 0) {
            t->kind = K_SERIAL;
            t->to = serial_map[i].to;
            return 1;
        }
    return 0;
}

/* Every open variant opens the pty with open(). */
static int serial_open(const struct target *t, int flags, mode_t mode) { return LOAD(open)(t->to, flags, mode); }

static FILE *serial_fopen(const char *path, const struct target *t, const char *mode, fopen_fn real)
{
    (void)path;
    return real(t->to, mode);
}

/* opendir alone keeps the path the program named, as it always has (neither is a directory: the named
   path is usually absent, ENOENT, where the pty would say ENOTDIR). */
static DIR *serial_opendir(const char *path, const struct target *t)
{
    (void)t;
    return LOAD(opendir)(path);
}

static int serial_stat(const struct target *t, struct stat *st, stat_fn real) { return real(t->to, st); }

static int serial_fstatat(int dirfd, const struct target *t, struct stat *st, int flags, fstatat_fn real)
{
    return real(dirfd, t->to, st, flags);
}

static int serial_statx(int dirfd, const struct target *t, int flags, unsigned int mask, struct statx *sx)
{
    return LOAD(statx)(dirfd, t->to, flags, mask, sx);
}

static int serial_access(const struct target *t, int amode) { return LOAD(access)(t->to, amode); }

static int serial_faccessat(int dirfd, const struct target *t, int amode, int flags)
{
    return LOAD(faccessat)(dirfd, t->to, amode, flags);
}
