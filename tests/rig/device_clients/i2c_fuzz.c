/* A C DUT for `rig exec` that fuzzes the i2c-dev surface: `i2c_fuzz SEED CALLS`. A forked child makes
   CALLS random calls from the seed (ioctl requests, lengths, flags, message counts, sizes, read_write
   values and pointers: NULL, small garbage, random non-user addresses, a PROT_NONE page, a read-only
   page, valid buffers in static memory and on the stack; read and write with random lengths) and checks each one returns or fails with
   an errno i2c-dev gives; the parent waits for it, says how it ended, then reads WHO_AM_I. Prints
   "key value..." lines. The pointers are never user addresses by chance, so a seed replays exactly. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#define BIG 65536 /* valid buffers: room for any 16-bit length from any of the first 64 offsets */
static unsigned char big[BIG + 64];
static struct i2c_msg msgs[64];
static struct i2c_rdwr_ioctl_data rdwr_arg;
static struct i2c_smbus_ioctl_data smbus_arg;
static unsigned char *none, *ro, *on_stack; /* on_stack: a valid buffer in fuzz()'s frame */
static uint64_t state;
static volatile long *progress; /* shared with the parent: the call being made */

static uint64_t rnd(void) /* xorshift64* */
{
    state ^= state >> 12;
    state ^= state << 25;
    state ^= state >> 27;
    return state * 2685821657736338717ull;
}

static unsigned pick(unsigned n) { return (unsigned)(rnd() % n); }

static void *pointer(void)
{
    switch (pick(10)) {
    case 0:
        return NULL;
    case 1:
        return (void *)(uintptr_t)(1 + pick(4095)); /* small garbage: the zero page */
    case 2: {
        uint64_t v = rnd();
        if (v >> 47 == 0)
            v |= 1ull << 63; /* a user-space address could be mapped: make it non-canonical */
        return (void *)(uintptr_t)v;
    }
    case 3:
        return none + pick(4096);
    case 4:
        return ro + pick(64);
    case 5:
        return on_stack + pick(64);
    default:
        return big + pick(64);
    }
}

static unsigned length(void)
{
    switch (pick(8)) {
    case 0:
        return 32 + pick(10); /* around a block's size */
    case 1:
        return 8190 + pick(4); /* around i2c-dev's limit */
    case 2:
        return pick(65536);
    default:
        return pick(20);
    }
}

static unsigned address(void)
{
    static const unsigned known[] = { 0x68, 0x77, 0x1e, 0x00, 0x7f };
    return pick(3) ? known[pick(5)] : pick(0x500);
}

static void fill(void *p, size_t n)
{
    if ((unsigned char *)p >= big && (unsigned char *)p < big + sizeof big)
        for (size_t i = 0; i < n && (unsigned char *)p + i < big + sizeof big; i++)
            ((unsigned char *)p)[i] = (unsigned char)rnd();
}

static long one_call(int fd, int *which)
{
    static const unsigned long unknown[] = { 0x0700, 0x0709, 0x5401, 0xdeadbeef };
    switch (*which = (int)pick(12)) {
    case 0:
        return ioctl(fd, pick(2) ? I2C_SLAVE : I2C_SLAVE_FORCE, (unsigned long)address());
    case 1:
        return ioctl(fd, I2C_TENBIT, (unsigned long)(pick(4) == 0));
    case 2:
        return ioctl(fd, I2C_FUNCS, pointer());
    case 3:
        return ioctl(fd, I2C_PEC, (unsigned long)(pick(4) == 0));
    case 4:
    case 5: {
        unsigned n = pick(8) ? 1 + pick(3) : pick(64);
        for (unsigned i = 0; i < n; i++) {
            msgs[i].addr = (uint16_t)address();
            msgs[i].flags = (uint16_t)(pick(6) ? (pick(2) ? I2C_M_RD : 0) | (pick(5) ? 0 : I2C_M_RECV_LEN) |
                                                     (pick(8) ? 0 : I2C_M_TEN)
                                               : rnd());
            msgs[i].len = (uint16_t)length();
            msgs[i].buf = pointer();
            fill(msgs[i].buf, 1);
        }
        rdwr_arg.msgs = pick(8) ? msgs : pointer();
        rdwr_arg.nmsgs = pick(10) ? n : (uint32_t)rnd();
        return ioctl(fd, I2C_RDWR, pick(8) ? (void *)&rdwr_arg : pointer());
    }
    case 6:
    case 7: {
        smbus_arg.read_write = (uint8_t)(pick(8) ? pick(2) : rnd());
        smbus_arg.command = (uint8_t)rnd();
        smbus_arg.size = pick(8) ? pick(9) : (uint32_t)rnd();
        smbus_arg.data = pointer();
        fill(smbus_arg.data, sizeof(union i2c_smbus_data));
        return ioctl(fd, I2C_SMBUS, pick(8) ? (void *)&smbus_arg : pointer());
    }
    case 8: {
        void *p = pointer();
        return read(fd, p, length());
    }
    case 9: {
        void *p = pointer();
        size_t n = length();
        fill(p, n);
        return write(fd, p, n);
    }
    case 10:
        return ioctl(fd, unknown[pick(4)], pointer());
    default:
        return ioctl(fd, pick(2) ? I2C_RETRIES : I2C_TIMEOUT, (unsigned long)pick(100));
    }
}

static int who_am_i(int fd)
{
    unsigned char reg = 0x75, id = 0;
    struct i2c_msg m[2] = { { 0x68, 0, 1, &reg }, { 0x68, I2C_M_RD, 1, &id } };
    struct i2c_rdwr_ioctl_data d = { m, 2 };
    if (ioctl(fd, I2C_TENBIT, 0) < 0 || ioctl(fd, I2C_RDWR, &d) != 2)
        return -1;
    return id;
}

static int fuzz(long calls)
{
    unsigned char stack_buf[BIG + 64];
    memset(stack_buf, 0, sizeof stack_buf);
    on_stack = stack_buf;
    int fd = open("/dev/i2c-1", O_RDWR);
    if (fd < 0) {
        perror("open /dev/i2c-1");
        return 2;
    }
    long ok = 0, efault = 0, other = 0, unexpected = 0;
    for (long i = 0; i < calls; i++) {
        *progress = i;
        int which;
        errno = 0;
        long r = one_call(fd, &which);
        int e = errno;
        if (r >= 0)
            ok++;
        else if (r == -1 && e == EFAULT)
            efault++;
        else if (r == -1 && (e == EINVAL || e == ENXIO || e == EPROTO || e == ENOTTY))
            other++;
        else if (unexpected++ < 10)
            printf("unexpected call %ld kind %d: %ld errno %d (%s)\n", i, which, r, e, strerror(e));
    }
    printf("child ok %ld efault %ld other_errors %ld unexpected %ld\n", ok, efault, other, unexpected);
    printf("child who_am_i 0x%02x\n", who_am_i(fd));
    fflush(stdout);
    return unexpected ? 1 : 0;
}

int main(int argc, char **argv)
{
    if (argc != 3)
        return 2;
    unsigned long long seed = strtoull(argv[1], NULL, 0);
    long calls = atol(argv[2]);
    state = seed ? seed : 1;
    printf("seed %llu calls %ld\n", seed, calls);
    fflush(stdout);
    none = mmap(NULL, 4096, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    ro = mmap(NULL, 4096, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    progress = mmap(NULL, sizeof *progress, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (none == MAP_FAILED || ro == MAP_FAILED || progress == MAP_FAILED)
        return 2;
    *progress = -1;
    pid_t child = fork();
    if (child == 0)
        _exit(fuzz(calls));
    int status = 0;
    waitpid(child, &status, 0);
    if (WIFSIGNALED(status))
        printf("child killed by signal %d (%s) in call %ld\n", WTERMSIG(status), strsignal(WTERMSIG(status)),
               *progress);
    else
        printf("child exit %d after %ld calls\n", WEXITSTATUS(status), *progress + 1);
    int fd = open("/dev/i2c-1", O_RDWR);
    printf("parent who_am_i 0x%02x\n", fd < 0 ? 0 : who_am_i(fd));
    return 0;
}
