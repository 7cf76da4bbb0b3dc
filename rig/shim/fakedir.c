/*
 * Directory streams on fake directories: glibc's readdir reads a descriptor with getdents64, which no
 * preload can redirect, so opendir and fdopendir on a fake directory (dispatch.c) give the shim's own
 * stream, whose entries the directory's kind lists (kind_ops.dir_entry); readdir, readdir64,
 * rewinddir, dirfd and closedir tell one of these streams from a real DIR by the list of those open.
 * Part of rigshim.c (one translation unit): see its top comment.
 */

struct fake_dir {
    struct fake_dir *next;
    int fd;
    struct target t;
    uint32_t start; /* what the kind's listing starts from (PWM: the exported channels), at open or rewind */
    long at;        /* the next entry */
    struct dirent64 ent;
};
_Static_assert(sizeof(struct dirent) == sizeof(struct dirent64), "struct dirent64 differs from struct dirent");
static struct fake_dir *fake_dirs;
static int n_fake_dirs;

static struct fake_dir *fake_dir_of(DIR *d)
{
    if (!__atomic_load_n(&n_fake_dirs, __ATOMIC_ACQUIRE))
        return NULL;
    LOAD(pthread_mutex_lock)(&lock);
    struct fake_dir *p = fake_dirs;
    while (p && (DIR *)p != d)
        p = p->next;
    pthread_mutex_unlock(&lock);
    return p;
}

static void dir_rewind(struct fake_dir *d)
{
    const struct kind_ops *k = &kinds[d->t.kind];
    d->start = k->dir_start ? k->dir_start(&d->t) : 0;
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
    LOAD(pthread_mutex_lock)(&lock);
    d->next = fake_dirs;
    fake_dirs = d;
    __atomic_add_fetch(&n_fake_dirs, 1, __ATOMIC_RELEASE);
    pthread_mutex_unlock(&lock);
    return (DIR *)d;
}

static struct dirent64 *dir_read(struct fake_dir *d)
{
    if (!kinds[d->t.kind].dir_entry(&d->t, d->start, d->at, &d->ent))
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
    LOAD(pthread_mutex_lock)(&lock);
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
