/* A C DUT for `rig exec` that reaches the devices through libc's other writes, as ArduPilot's Linux HAL
   does: dprintf and vdprintf on sysfs PWM attributes, writev and pwrite on them, a FILE from fdopen,
   writev onto /dev/i2c-1 (one message per piece) and dprintf onto a serial path. Prints one "name
   value" line per result (the call's return value, -1 with the errno's name after it). */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/uio.h>
#include <unistd.h>

#define CHIP "/sys/class/pwm/pwmchip0"

static void report(const char *name, long r)
{
    if (r < 0)
        printf("%s -1 %s\n", name, strerrorname_np(errno));
    else
        printf("%s %ld\n", name, r);
}

static int open_attr(int channel, const char *attr)
{
    char path[96];
    snprintf(path, sizeof path, CHIP "/pwm%d/%s", channel, attr);
    return open(path, O_WRONLY);
}

static int through_vdprintf(int fd, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vdprintf(fd, fmt, ap);
    va_end(ap);
    return n;
}

int main(void)
{
    int exp = open(CHIP "/export", O_WRONLY);
    report("dprintf_export", dprintf(exp, "%d", 0));
    report("vdprintf_export", through_vdprintf(exp, "%d\n", 1));
    struct iovec two[2] = { { "2", 1 }, { "\n", 1 } };
    report("writev_export", writev(exp, two, 2));
    report("pwrite_export", pwrite(exp, "3", 1, 0));
    report("dprintf_export_again", dprintf(exp, "%d", 0)); /* EBUSY, as the pwm class answers */
    close(exp);

    /* channel 0 by dprintf, 1 by vdprintf, 2 by writev, 3 by a FILE from fdopen */
    int p0 = open_attr(0, "period"), d0 = open_attr(0, "duty_cycle"), e0 = open_attr(0, "enable");
    report("dprintf_period", dprintf(p0, "%u", 2500000u));
    report("dprintf_duty", dprintf(d0, "%u", 1100000u));
    report("dprintf_duty_above_period", dprintf(d0, "%u", 3000000u));
    report("dprintf_enable", dprintf(e0, "1"));
    int p1 = open_attr(1, "period"), d1 = open_attr(1, "duty_cycle"), e1 = open_attr(1, "enable");
    through_vdprintf(p1, "%u", 2500000u);
    report("vdprintf_duty", through_vdprintf(d1, "%u\n", 1200000u));
    through_vdprintf(e1, "1");
    int p2 = open_attr(2, "period"), d2 = open_attr(2, "duty_cycle"), e2 = open_attr(2, "enable");
    report("pwrite_period", pwrite(p2, "2500000", 7, 0));
    struct iovec duty[3] = { { "1300", 4 }, { "000", 3 }, { "\n", 1 } };
    report("writev_duty", writev(d2, duty, 3)); /* one store of "1300000\n", as kernfs joins them */
    report("pwrite64_enable", pwrite64(e2, "1", 1, 0));
    FILE *p3 = fdopen(open_attr(3, "period"), "w"), *d3 = fdopen(open_attr(3, "duty_cycle"), "w");
    FILE *e3 = fdopen(open_attr(3, "enable"), "w");
    fprintf(p3, "%u\n", 2500000u);
    report("fdopen_period_fclose", fclose(p3));
    fprintf(d3, "%u\n", 1400000u);
    report("fdopen_duty_fclose", fclose(d3));
    fputs("1\n", e3);
    report("fdopen_enable_fclose", fclose(e3));
    FILE *bad = fdopen(open(CHIP "/pwm3/duty_cycle", O_RDONLY), "w");
    report("fdopen_mode_refused", bad ? 0 : -1);

    /* the bus: writev's pieces are two messages, a register pointer then a value */
    int bus = open("/dev/i2c-1", O_RDWR);
    ioctl(bus, I2C_SLAVE, 0x68);
    struct iovec wake[2] = { { "\x6b\x00", 2 }, { "\x75", 1 } };
    report("writev_i2c", writev(bus, wake, 2));
    unsigned char who = 0;
    read(bus, &who, 1);
    report("who_am_i", who);
    ioctl(bus, I2C_SLAVE, 0x50);
    struct iovec nobody[1] = { { "\x00", 1 } };
    report("writev_i2c_nack", writev(bus, nobody, 1));

    int tty = open("/dev/ttyRC0", O_RDWR | O_NOCTTY);
    report("dprintf_serial", dprintf(tty, "hello %d", 42));
    struct iovec line[2] = { { " and", 4 }, { " more", 5 } };
    report("writev_serial", writev(tty, line, 2));
    sleep(2); /* the motors settle (ESC time constant 20 ms) */
    return 0;
}
