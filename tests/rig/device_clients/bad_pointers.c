/* A C DUT for `rig exec`: hands i2c-dev and sysfs PWM descriptors pointers the kernel refuses with
   EFAULT (garbage, NULL where the kernel copies, a PROT_NONE page, a read-only page to write into),
   then reads WHO_AM_I. Prints one "name result" line per call: "ok" (or "ok N" with the value
   returned) or the errno's name. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#define CHIP "/sys/class/pwm/pwmchip0"

static volatile uintptr_t garbage = 0x10; /* read at run time: gcc would flag a constant as overflowing */
#define BAD ((void *)garbage)

static void report(const char *name, long r)
{
    int e = errno;
    if (r >= 0)
        printf("%s ok %ld\n", name, r);
    else
        printf("%s %s\n", name, e == EFAULT ? "EFAULT" : e == EINVAL ? "EINVAL" : strerror(e));
    fflush(stdout);
}

/* The top of the main thread's stack ([stack] in /proc/self/maps): a buffer that starts below it and
   ends above it starts in mapped memory and runs into none. */
static char *stack_top(void)
{
    FILE *maps = fopen("/proc/self/maps", "r");
    char line[256];
    unsigned long lo = 0, hi = 0;
    while (maps && fgets(line, sizeof line, maps))
        if (strstr(line, "[stack]"))
            sscanf(line, "%lx-%lx", &lo, &hi);
    if (maps)
        fclose(maps);
    return (char *)hi;
}

static long rdwr(int fd, struct i2c_msg *m, unsigned n)
{
    struct i2c_rdwr_ioctl_data d = { m, n };
    return ioctl(fd, I2C_RDWR, &d);
}

static long smbus(int fd, int rw, int cmd, int size, void *data)
{
    struct i2c_smbus_ioctl_data a = { (unsigned char)rw, (unsigned char)cmd, (unsigned)size, data };
    return ioctl(fd, I2C_SMBUS, &a);
}

int main(void)
{
    char *none = mmap(NULL, 4096, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    char *ro = mmap(NULL, 4096, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    int fd = open("/dev/i2c-1", O_RDWR);
    if (none == MAP_FAILED || ro == MAP_FAILED || fd < 0 || ioctl(fd, I2C_SLAVE, 0x68) < 0) {
        perror("set-up");
        return 2;
    }
    unsigned char reg = 0x75, id = 0;

    report("funcs_garbage", ioctl(fd, I2C_FUNCS, (void *)0x1234));
    report("funcs_null", ioctl(fd, I2C_FUNCS, NULL));
    report("funcs_readonly", ioctl(fd, I2C_FUNCS, ro));
    report("write_garbage", write(fd, BAD, 4));
    report("write_prot_none", write(fd, none, 4));
    report("read_garbage", read(fd, BAD, 4));
    report("read_readonly", read(fd, ro, 1));
    char *top = stack_top();
    report("write_past_stack_top", top ? write(fd, top - 4, 8) : -2);

    report("rdwr_arg_garbage", ioctl(fd, I2C_RDWR, (void *)0x1234));
    struct i2c_rdwr_ioctl_data d = { BAD, 2 };
    report("rdwr_msgs_garbage", ioctl(fd, I2C_RDWR, &d));
    d.msgs = (struct i2c_msg *)(none + 4096 - sizeof(struct i2c_msg));
    report("rdwr_msgs_prot_none", ioctl(fd, I2C_RDWR, &d));
    struct i2c_msg m[2] = { { 0x68, 0, 1, &reg }, { 0x68, I2C_M_RD, 1, &id } };
    d = (struct i2c_rdwr_ioctl_data){ NULL, 1 };
    report("rdwr_msgs_null", ioctl(fd, I2C_RDWR, &d)); /* i2c-dev since 5.11: EINVAL */
    d = (struct i2c_rdwr_ioctl_data){ m, 0 };
    report("rdwr_no_msgs", ioctl(fd, I2C_RDWR, &d));
    m[0].buf = BAD;
    report("rdwr_write_buf_garbage", rdwr(fd, m, 2));
    m[0].buf = &reg;
    m[1].buf = BAD;
    report("rdwr_read_buf_garbage", rdwr(fd, m, 2));
    m[1].buf = (unsigned char *)ro;
    report("rdwr_read_buf_readonly", rdwr(fd, m, 2));
    m[1].buf = (unsigned char *)none;
    report("rdwr_read_buf_prot_none", rdwr(fd, m, 2));
    m[1].buf = &id;
    struct i2c_msg past_top[2] = { { 0x68, 0, 8, (unsigned char *)top - 4 }, m[1] };
    report("rdwr_write_buf_past_stack_top", rdwr(fd, past_top, 2));
    struct i2c_msg empty = { 0x68, 0, 0, BAD }; /* nothing to copy: no fault */
    report("rdwr_empty_message_garbage_buf", rdwr(fd, &empty, 1));

    report("smbus_arg_garbage", ioctl(fd, I2C_SMBUS, (void *)0x1234));
    report("smbus_read_byte_data_garbage", smbus(fd, I2C_SMBUS_READ, 0x75, I2C_SMBUS_BYTE_DATA, BAD));
    report("smbus_read_byte_data_readonly", smbus(fd, I2C_SMBUS_READ, 0x75, I2C_SMBUS_BYTE_DATA, ro));
    report("smbus_write_byte_data_garbage", smbus(fd, I2C_SMBUS_WRITE, 0x6B, I2C_SMBUS_BYTE_DATA, BAD));
    report("smbus_read_word_prot_none", smbus(fd, I2C_SMBUS_READ, 0x75, I2C_SMBUS_WORD_DATA, none));
    report("smbus_i2c_block_garbage", smbus(fd, I2C_SMBUS_READ, 0x75, I2C_SMBUS_I2C_BLOCK_DATA, BAD));
    report("smbus_block_write_garbage", smbus(fd, I2C_SMBUS_WRITE, 0x6B, I2C_SMBUS_BLOCK_DATA, BAD));
    report("smbus_proc_call_garbage", smbus(fd, I2C_SMBUS_WRITE, 0x25, I2C_SMBUS_PROC_CALL, BAD));

    int efd = open(CHIP "/export", O_WRONLY);
    report("pwm_export_write_garbage", write(efd, BAD, 2));
    report("pwm_export", write(efd, "0", 1));
    int pfd = open(CHIP "/pwm0/period", O_RDWR);
    report("pwm_period_write_garbage", write(pfd, BAD, 7));
    report("pwm_period_pwrite_prot_none", pwrite(pfd, none, 7, 0));
    report("pwm_period_read_garbage", read(pfd, BAD, 8));
    report("pwm_period_pread_readonly", pread(pfd, ro, 8, 0));
    report("pwm_period_write", write(pfd, "2500000", 7));
    char text[16] = "";
    report("pwm_period_pread", pread(pfd, text, sizeof text - 1, 0));
    printf("pwm_period_value %s", text);

    id = 0;
    m[1].buf = &id;
    report("who_am_i_rdwr", rdwr(fd, m, 2));
    printf("who_am_i 0x%02x\n", id);
    union i2c_smbus_data data = { 0 };
    report("who_am_i_smbus", smbus(fd, I2C_SMBUS_READ, 0x75, I2C_SMBUS_BYTE_DATA, &data));
    printf("who_am_i_smbus_value 0x%02x\n", data.byte);
    return 0;
}
