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
 *   link.c       the socket to the session: connect, send, request, notice, note
 *   vtime.c      virtual time: the clocks, the sleeps, the poll family's timeouts
 *   usermem.c    the caller's memory copied as the kernel copies it (EFAULT, never a crash)
 *   paths.c      what a path names (a target) and what stat shows for it
 *   fdtable.c    fake descriptors: the table, backing files, adoption after exec, close/dup/fcntl, stdio
 *   fakedir.c    directory streams on fake directories (readdir, closedir, ...)
 *   i2cdev.c     i2c-dev: transfers, I2C_RDWR, SMBus, its ioctls
 *   sysfs_pwm.c  the sysfs PWM class's attributes
 *   dispatch.c   the interposed calls on paths and descriptors that may be a device's
 * and ends with the start-up (the constructor), which reads the environment the session set.
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
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdio_ext.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/mman.h>
#include <sys/select.h>
#include <sys/sendfile.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/sysmacros.h>
#include <sys/time.h>
#include <sys/uio.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>
#include <wchar.h>

#include "protocol.h"

#define EXPORT __attribute__((visibility("default")))
#define MAX_FD 65536
#define MAX_SERIAL 8
#define I2C_MAJOR 89
#define MAX_XFER 8192 /* i2c-dev's limit for one message and for read()/write() */

/* ---------------------------------------------------------------- what every part shares */

static int active;              /* RIG_SOCKET set: redirect */
static int lockstep;            /* RIG_LOCKSTEP=1: virtual time */
static unsigned i2c_buses_mask; /* bit N: /dev/i2c-N is emulated (N < 32) */
static int pwm_chip;
static struct rig_shm *shm;
static struct {
    char from[128];
    char to[128];
} serial_map[MAX_SERIAL];
static int n_serial;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;

static void parse_serial(const char *spec)
{
    while (spec && *spec && n_serial < MAX_SERIAL) {
        const char *end = strchr(spec, ':');
        size_t n = end ? (size_t)(end - spec) : strlen(spec);
        const char *eq = memchr(spec, '=', n);
        if (eq && (size_t)(eq - spec) < sizeof serial_map[0].from && n - (size_t)(eq - spec) - 1 < sizeof serial_map[0].to) {
            memcpy(serial_map[n_serial].from, spec, (size_t)(eq - spec));
            memcpy(serial_map[n_serial].to, eq + 1, n - (size_t)(eq - spec) - 1);
            n_serial++;
        }
        spec = end ? end + 1 : NULL;
    }
}

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

#include "real_libc.c"
#include "link.c"
#include "vtime.c"
#include "usermem.c"
#include "paths.c"
#include "fdtable.c"
#include "fakedir.c"
#include "i2cdev.c"
#include "sysfs_pwm.c"
#include "dispatch.c"

/* ---------------------------------------------------------------- start-up */

static void after_fork_child(void)
{
    own_pid = getpid();
    reset_std_lock();
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
    const char *b = getenv("RIG_I2C_BUSES");
    for (; b && *b; b++) {
        char *end;
        long n = strtol(b, &end, 10);
        if (end != b && n >= 0 && n < 32)
            i2c_buses_mask |= 1u << n;
        b = *end ? end : end - 1;
    }
    const char *chip = getenv("RIG_PWM_CHIP");
    pwm_chip = chip ? atoi(chip) : 0;
    parse_serial(getenv("RIG_SERIAL"));
    const char *ls = getenv("RIG_LOCKSTEP");
    lockstep = ls && strcmp(ls, "1") == 0;
    const char *fk = getenv("RIG_FAKES");
    if (fk && fk[0] == '/' && strlen(fk) < sizeof fakes_dir - 64)
        strcpy(fakes_dir, fk);
    own_pid = getpid();
    pthread_atfork(NULL, NULL, after_fork_child);
    active = 1;
    adopt_inherited_fakes();
}
