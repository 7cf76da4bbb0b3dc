/*
 * rigshim: preloaded into an unmodified DUT (LD_PRELOAD) by `rig exec`. It redirects
 *   - /dev/i2c-N (the buses in RIG_I2C_BUSES) to the session's emulated bus,
 *   - /sys/class/pwm/pwmchip0/... to PWM channels kept in the shared page (and reported to the session),
 *   - chosen serial paths (RIG_SERIAL="/dev/ttyRC0=/dev/pts/5:...") to ptys the session owns,
 *   - in lockstep (RIG_LOCKSTEP=1), the clocks and every wait to the session's virtual time.
 * Everything else passes through to libc. Without RIG_SOCKET in the environment the shim does nothing.
 *
 * Why this shape: the kernel's i2c-dev, sysfs and clock behaviour is reproduced here, in the DUT's own
 * process, so that only the bytes of a transfer and the wish to wait cross the socket. Clock reads and
 * PWM writes never wait for the session (docs/design.md section 6).
 *
 * The parts: this file is the shim's only translation unit; it includes the others in this order, each
 * a concern, so each can be read alone while the compiler still sees one file (static functions inline
 * across parts, nothing more is exported: -fvisibility=hidden, EXPORT marks the interposers):
 *   real_libc.c  the real functions behind the interposed ones (LOAD), errno_ret
 *   link.c       the socket to the session: connect, send, request, notice (held in lockstep), note
 *   vtime.c      virtual time: the clocks, the sleeps, the poll family's timeouts
 *   priorities.c real-time policies and mlockall: recorded, not applied, in lockstep
 *   vtimers.c    virtual timers: timerfd, alarm and setitimer on the session's clock
 *   threads.c    many threads in one virtual time: the rule that picks who runs; thread lifetimes
 *   sync.c       mutexes, read-write locks, condition variables, semaphores, barriers under the rule
 *   usermem.c    the caller's memory copied as the kernel copies it (EFAULT, never a crash)
 *   paths.c      what a path names (classify: a target), the shape of a device kind (struct kind_ops)
 *   fdtable.c    fake descriptors: the table, backing files, adoption after exec, close/dup/fcntl, stdio
 *   fakedir.c    directory streams on fake directories (readdir, closedir, ...)
 *   i2cdev.c     the kind K_I2C: i2c-dev (transfers, I2C_RDWR, SMBus, its ioctls, read/write)
 *   serial.c     the kind K_SERIAL: serial paths that are the session's ptys
 *   sysfs_pwm.c  the kinds K_PWM_ATTR and K_PWM_DIR: the sysfs PWM class's attributes and directories
 *   kinds[]      (here) the table of the kinds' operations, one row per kind
 *   dispatch.c   the interposed calls on paths and descriptors that may be a device's
 *   process_ends.c  exec, spawn, wait and _exit: the notices link.c holds go first
 * and ends with the start-up (the constructor), which reads the environment the session set.
 *
 * The device kinds: everything that differs between devices sits in the kind's file and is reached
 * through its row in kinds[] (struct kind_ops, paths.c): which paths are its, what stat shows, open,
 * fopen, opendir, read, write, pread, pwrite, lseek, ioctl, ... An operation a row leaves NULL gets the
 * generic answer for a device file the shim emulates behind a fake descriptor (dispatch.c), so the
 * interposers dispatch through the table and never test a kind.
 *
 * Adding a device kind (SPI, GPIO) is one file and one table row: a file (say spidev.c) with the
 * kind's claim (the paths that are its), init (its configuration from the environment), name and
 * fill_stat, and the calls it answers otherwise than the generic answer (for spidev: read, write,
 * ioctl, and ESPIPE for pread, pwrite and lseek as i2cdev.c does); then, here, its #include among the
 * kinds, a constant in enum kind (its place is its turn to look at a path) and its row in kinds[].
 * dispatch.c, fdtable.c and fakedir.c serve every kind unchanged. A target names the file with bus,
 * channel and attr; state kept per open descriptor (i2c-dev's client address) is a field of struct
 * fake. A device that needs the session (a transfer) also needs its message in protocol.h and its
 * handling in rig/protocol.py and rig/handler.py.
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <semaphore.h>
#include <signal.h>
#include <spawn.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdio_ext.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <sys/select.h>
#include <sys/sendfile.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/sysmacros.h>
#include <sys/time.h>
#include <sys/timerfd.h>
#include <sys/uio.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <wchar.h>

#include "protocol.h"

#define EXPORT __attribute__((visibility("default")))
#define MAX_FD 65536
#define MAX_XFER 8192 /* i2c-dev's limit for one message and for read()/write() */

/* ---------------------------------------------------------------- what every part shares */

static int active;   /* RIG_SOCKET set: redirect */
static int lockstep; /* RIG_LOCKSTEP=1: virtual time */
static struct rig_shm *shm;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;

/* This process's pid, kept: getpid() is a syscall (glibc no longer caches it), and every message asks.
   Set at start-up and in a fork's child (pthread_atfork), so it is never 0 once the shim runs: a vfork
   child (Python's subprocess, between vfork and exec) shares the parent's memory, own_pid included,
   and tells itself apart by getpid() (see set_fake). posix_spawn children only exec. */
static pid_t own_pid;
static pid_t self_pid(void)
{
    if (!own_pid)
        own_pid = getpid();
    return own_pid;
}

/* ---------------------------------------------------------------- the parts, in order */

/* the parts in the order they need each other (not sorted) */
// clang-format off
#include "real_libc.c"
#include "link.c"
#include "vtime.c"
#include "priorities.c"
#include "vtimers.c"
#include "threads.c"
#include "sync.c"
#include "usermem.c"
// clang-format on

/* The device kinds, in the order they look at a path (the first to claim it decides): each is a file
   included below and a row in kinds[]. */
enum kind { K_NONE, K_I2C, K_SERIAL, K_PWM_ATTR, K_PWM_DIR, N_KINDS };

// clang-format off
#include "paths.c"
#include "fdtable.c"
#include "fakedir.c"
// clang-format on

/* the kinds */
#include "i2cdev.c"
#include "serial.c"
#include "sysfs_pwm.c"

/* ---------------------------------------------------------------- the kinds' operations */

/* One row per kind: its operations (struct kind_ops, paths.c); what a row leaves out is the generic
   answer (dispatch.c). */
static const struct kind_ops kinds[N_KINDS] = {
    [K_I2C] = {
        .claim = i2c_claim,
        .init = i2c_init,
        .name = i2c_name,
        .fill_stat = i2c_fill_stat,
        .fopen = i2c_fopen,
        .read = i2c_read,
        .write = i2c_write,
        .pread = i2c_pread,
        .pwrite = i2c_pwrite,
        .seek = i2c_seek,
        .ioctl = i2c_ioctl,
    },
    [K_SERIAL] = {
        .claim = serial_claim,
        .init = serial_init,
        .open = serial_open,
        .fopen = serial_fopen,
        .opendir = serial_opendir,
        .stat = serial_stat,
        .fstatat = serial_fstatat,
        .statx = serial_statx,
        .access = serial_access,
        .faccessat = serial_faccessat,
    },
    [K_PWM_ATTR] = {
        .claim = pwm_claim, /* for K_PWM_DIR too */
        .init = pwm_init,
        .name = pwm_attr_name,
        .fill_stat = pwm_attr_fill_stat,
        .open = pwm_attr_open,
        .read = pwm_attr_read,
        .write = pwm_attr_write,
        .sendfile = 1,
        .gather = 1,
    },
    [K_PWM_DIR] = {
        .name = pwm_dir_name,
        .fill_stat = pwm_dir_fill_stat,
        .open = pwm_dir_open,
        .read = pwm_dir_read,
        .dir_start = pwm_dir_start,
        .dir_entry = pwm_dir_entry,
    },
};

#include "dispatch.c"
#include "process_ends.c"

/* ---------------------------------------------------------------- start-up */

/* The notices held (link.c) are the process's own: they go before a fork (the child starts without
   them) and before the process ends. */
__attribute__((destructor)) static void shim_fini(void) { send_held_now(); }

static void after_fork_child(void)
{
    own_pid = getpid();
    reset_std_lock();
    threads_after_fork();
}

__attribute__((constructor)) static void shim_init(void)
{
    const char *s = getenv("RIG_SOCKET");
    if (!s || !*s || strlen(s) >= sizeof sock_path)
        return;
    strcpy(sock_path, s);
    const char *shm_path = getenv("RIG_SHM");
    int fd = shm_path ? LOAD(open)(shm_path, O_RDWR | O_CLOEXEC) : -1;
    if (fd < 0) {
        fprintf(stderr, "rigshim: cannot open the shared page RIG_SHM=%s: %s\n", shm_path ? shm_path : "(unset)",
                strerror(errno));
        return;
    }
    void *p = mmap(NULL, sizeof(struct rig_shm), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    LOAD(close)(fd);
    if (p == MAP_FAILED || ((struct rig_shm *)p)->magic != RIG_SHM_MAGIC) {
        fprintf(stderr, "rigshim: RIG_SHM=%s is not a rig shared page\n", shm_path);
        return;
    }
    shm = p;
    for (int k = K_NONE + 1; k < N_KINDS; k++)
        if (kinds[k].init)
            kinds[k].init();
    const char *ls = getenv("RIG_LOCKSTEP");
    lockstep = ls && strcmp(ls, "1") == 0;
    const char *spin = getenv("RIG_SPIN_NS");
    spin_ns = lockstep && spin ? strtoull(spin, NULL, 10) : 0;
    if (spin_ns > 10000000u) /* (10 ms: more would only burn the core) */
        spin_ns = 10000000u;
    const char *fk = getenv("RIG_FAKES");
    if (fk && fk[0] == '/' && strlen(fk) < sizeof fakes_dir - 64)
        strcpy(fakes_dir, fk);
    own_pid = getpid();
    threads_init();
    pthread_atfork(send_held_now, NULL, after_fork_child);
    active = 1;
    adopt_inherited_fakes();
}
