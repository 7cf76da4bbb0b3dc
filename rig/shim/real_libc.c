/*
 * The real libc functions behind the ones the shim interposes, found with dlsym(RTLD_NEXT) on first
 * use (LOAD), and errno_ret, the -1-and-errno answer every interposer gives. Part of rigshim.c (one
 * translation unit): see its top comment.
 */

#define REAL(name) real_##name
#define DECLARE_REAL(ret, name, ...) static ret (*real_##name)(__VA_ARGS__)
DECLARE_REAL(int, open, const char *, int, ...);
DECLARE_REAL(int, open64, const char *, int, ...);
DECLARE_REAL(int, openat, int, const char *, int, ...);
DECLARE_REAL(int, openat64, int, const char *, int, ...);
DECLARE_REAL(int, __open_2, const char *, int);
DECLARE_REAL(int, __open64_2, const char *, int);
DECLARE_REAL(int, __openat_2, int, const char *, int);
DECLARE_REAL(int, __openat64_2, int, const char *, int);
DECLARE_REAL(FILE *, fopen, const char *, const char *);
DECLARE_REAL(FILE *, fopen64, const char *, const char *);
DECLARE_REAL(int, close, int);
DECLARE_REAL(ssize_t, read, int, void *, size_t);
DECLARE_REAL(ssize_t, write, int, const void *, size_t);
DECLARE_REAL(ssize_t, pread, int, void *, size_t, off_t);
DECLARE_REAL(ssize_t, pwrite, int, const void *, size_t, off_t);
DECLARE_REAL(ssize_t, pread64, int, void *, size_t, off_t);
DECLARE_REAL(ssize_t, pwrite64, int, const void *, size_t, off_t);
DECLARE_REAL(off_t, lseek, int, off_t, int);
DECLARE_REAL(off_t, lseek64, int, off_t, int);
DECLARE_REAL(int, ioctl, int, unsigned long, ...);
DECLARE_REAL(int, dup, int);
DECLARE_REAL(int, dup2, int, int);
DECLARE_REAL(int, dup3, int, int, int);
DECLARE_REAL(int, fcntl, int, int, ...);
DECLARE_REAL(int, fcntl64, int, int, ...);
DECLARE_REAL(DIR *, opendir, const char *);
DECLARE_REAL(DIR *, fdopendir, int);
DECLARE_REAL(struct dirent *, readdir, DIR *);
DECLARE_REAL(struct dirent64 *, readdir64, DIR *);
DECLARE_REAL(int, closedir, DIR *);
DECLARE_REAL(int, dirfd, DIR *);
DECLARE_REAL(void, rewinddir, DIR *);
DECLARE_REAL(ssize_t, copy_file_range, int, off64_t *, int, off64_t *, size_t, unsigned int);
DECLARE_REAL(ssize_t, sendfile, int, int, off_t *, size_t);
DECLARE_REAL(ssize_t, writev, int, const struct iovec *, int);
DECLARE_REAL(int, vdprintf, int, const char *, va_list);
DECLARE_REAL(int, __vdprintf_chk, int, int, const char *, va_list);
DECLARE_REAL(FILE *, fdopen, int, const char *);
DECLARE_REAL(int, sched_setscheduler, pid_t, int, const struct sched_param *);
DECLARE_REAL(int, sched_setparam, pid_t, const struct sched_param *);
DECLARE_REAL(int, pthread_setschedparam, pthread_t, int, const struct sched_param *);
DECLARE_REAL(int, pthread_setschedprio, pthread_t, int);
DECLARE_REAL(int, mlockall, int);
DECLARE_REAL(int, munlockall, void);
DECLARE_REAL(int, pthread_create, pthread_t *, const pthread_attr_t *, void *(*)(void *), void *);
/* the shim's own locks take the real pthread_mutex_lock (LOAD), never the rule's (threads.c) */
DECLARE_REAL(int, pthread_mutex_lock, pthread_mutex_t *);
DECLARE_REAL(int, pthread_mutex_trylock, pthread_mutex_t *);
DECLARE_REAL(int, pthread_mutex_unlock, pthread_mutex_t *);
DECLARE_REAL(int, pthread_mutex_timedlock, pthread_mutex_t *, const struct timespec *);
DECLARE_REAL(void, pthread_exit, void *);
DECLARE_REAL(int, pthread_join, pthread_t, void **);
DECLARE_REAL(int, sched_yield, void);
DECLARE_REAL(int, pthread_cond_wait, pthread_cond_t *, pthread_mutex_t *);
DECLARE_REAL(int, pthread_cond_timedwait, pthread_cond_t *, pthread_mutex_t *, const struct timespec *);
DECLARE_REAL(int, pthread_cond_clockwait, pthread_cond_t *, pthread_mutex_t *, clockid_t, const struct timespec *);
DECLARE_REAL(int, pthread_cond_signal, pthread_cond_t *);
DECLARE_REAL(int, pthread_cond_broadcast, pthread_cond_t *);
DECLARE_REAL(int, sem_wait, sem_t *);
DECLARE_REAL(int, sem_trywait, sem_t *);
DECLARE_REAL(int, sem_timedwait, sem_t *, const struct timespec *);
DECLARE_REAL(int, sem_clockwait, sem_t *, clockid_t, const struct timespec *);
DECLARE_REAL(int, timerfd_create, int, int);
DECLARE_REAL(int, timerfd_settime, int, int, const struct itimerspec *, struct itimerspec *);
DECLARE_REAL(int, timerfd_gettime, int, struct itimerspec *);
DECLARE_REAL(unsigned int, alarm, unsigned int);
DECLARE_REAL(int, setitimer, __itimer_which_t, const struct itimerval *, struct itimerval *);
DECLARE_REAL(int, getitimer, __itimer_which_t, struct itimerval *);
DECLARE_REAL(int, pause, void);
DECLARE_REAL(int, pthread_barrier_init, pthread_barrier_t *, const pthread_barrierattr_t *, unsigned);
DECLARE_REAL(int, pthread_barrier_destroy, pthread_barrier_t *);
DECLARE_REAL(int, pthread_barrier_wait, pthread_barrier_t *);
DECLARE_REAL(int, pthread_rwlock_rdlock, pthread_rwlock_t *);
DECLARE_REAL(int, pthread_rwlock_wrlock, pthread_rwlock_t *);
DECLARE_REAL(int, pthread_rwlock_tryrdlock, pthread_rwlock_t *);
DECLARE_REAL(int, pthread_rwlock_trywrlock, pthread_rwlock_t *);
DECLARE_REAL(int, pthread_rwlock_unlock, pthread_rwlock_t *);
DECLARE_REAL(int, pthread_rwlock_timedrdlock, pthread_rwlock_t *, const struct timespec *);
DECLARE_REAL(int, pthread_rwlock_timedwrlock, pthread_rwlock_t *, const struct timespec *);
DECLARE_REAL(int, pthread_rwlock_clockrdlock, pthread_rwlock_t *, clockid_t, const struct timespec *);
DECLARE_REAL(int, pthread_rwlock_clockwrlock, pthread_rwlock_t *, clockid_t, const struct timespec *);
DECLARE_REAL(ssize_t, sendfile64, int, int, off64_t *, size_t);
DECLARE_REAL(int, stat, const char *, struct stat *);
DECLARE_REAL(int, stat64, const char *, struct stat64 *);
DECLARE_REAL(int, lstat, const char *, struct stat *);
DECLARE_REAL(int, lstat64, const char *, struct stat64 *);
DECLARE_REAL(int, fstat, int, struct stat *);
DECLARE_REAL(int, fstat64, int, struct stat64 *);
DECLARE_REAL(int, fstatat, int, const char *, struct stat *, int);
DECLARE_REAL(int, fstatat64, int, const char *, struct stat64 *, int);
DECLARE_REAL(int, statx, int, const char *, int, unsigned int, struct statx *);
DECLARE_REAL(int, access, const char *, int);
DECLARE_REAL(int, faccessat, int, const char *, int, int);
DECLARE_REAL(int, clock_gettime, clockid_t, struct timespec *);
DECLARE_REAL(int, gettimeofday, struct timeval *, void *);
DECLARE_REAL(time_t, time, time_t *);
DECLARE_REAL(int, nanosleep, const struct timespec *, struct timespec *);
DECLARE_REAL(int, clock_nanosleep, clockid_t, int, const struct timespec *, struct timespec *);
DECLARE_REAL(int, usleep, useconds_t);
DECLARE_REAL(unsigned int, sleep, unsigned int);
DECLARE_REAL(int, poll, struct pollfd *, nfds_t, int);
DECLARE_REAL(int, ppoll, struct pollfd *, nfds_t, const struct timespec *, const sigset_t *);
DECLARE_REAL(int, select, int, fd_set *, fd_set *, fd_set *, struct timeval *);
DECLARE_REAL(int, pselect, int, fd_set *, fd_set *, fd_set *, const struct timespec *, const sigset_t *);
DECLARE_REAL(int, epoll_wait, int, struct epoll_event *, int, int);
DECLARE_REAL(int, epoll_pwait, int, struct epoll_event *, int, int, const sigset_t *);

static void *resolve(const char *name)
{
    void *p = dlsym(RTLD_NEXT, name);
    if (!p) {
        fprintf(stderr, "rigshim: libc has no %s\n", name);
        abort();
    }
    return p;
}
#define LOAD(name)                        \
    ({                                    \
        if (!real_##name)                 \
            real_##name = resolve(#name); \
        real_##name;                      \
    })

static int errno_ret(int err)
{
    errno = err;
    return -1;
}
