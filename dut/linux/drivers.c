/* Drivers: the sequences of docs/sensors.md section 7 for the MPU-6050, HMC5883L and MS5611, through
   the i2c-dev ioctls a real board uses, and motors through the Linux sysfs PWM class. */
#include "drivers.h"
#include "gy86.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

int i2c_open(const char *path) { return open(path, O_RDWR | O_CLOEXEC); }

int i2c_xfer(int fd, int addr, const uint8_t *w, int wn, uint8_t *r, int rn)
{
    struct i2c_msg m[2];
    int n = 0;
    if (wn > 0)
        m[n++] = (struct i2c_msg){ (uint16_t)addr, 0, (uint16_t)wn, (uint8_t *)w };
    if (rn > 0)
        m[n++] = (struct i2c_msg){ (uint16_t)addr, I2C_M_RD, (uint16_t)rn, r };
    struct i2c_rdwr_ioctl_data d = { m, (uint32_t)n };
    return ioctl(fd, I2C_RDWR, &d) < 0 ? -errno : 0;
}

static int wreg(int fd, int addr, uint8_t reg, uint8_t v)
{
    uint8_t b[2] = { reg, v };
    return i2c_xfer(fd, addr, b, 2, NULL, 0);
}

static int rregs(int fd, int addr, uint8_t reg, uint8_t *out, int n) { return i2c_xfer(fd, addr, &reg, 1, out, n); }

static void pause_ms(int ms)
{
    struct timespec ts = { 0, ms * 1000000L };
    nanosleep(&ts, NULL);
}

#define ACC_LSB_PER_G 8192.0  /* +-4 g */
#define GYRO_LSB_PER_DPS 16.4 /* +-2000 dps */

int mpu_init(int fd, int addr, char *err, int errlen)
{
    uint8_t id = 0;
    int r = rregs(fd, addr, 0x75, &id, 1);
    if (r < 0) {
        snprintf(err, (size_t)errlen, "MPU-6050: no answer at 0x%02x (%s)", addr, strerror(-r));
        return -1;
    }
    if ((id & 0x7E) != 0x68) {
        snprintf(err, (size_t)errlen, "MPU-6050: wrong WHO_AM_I 0x%02x at 0x%02x (expected 0x68)", id, addr);
        return -1;
    }
    for (size_t i = 0; i < MPU_SETUP_N; i++) {
        if ((r = wreg(fd, addr, mpu_setup[i][0], mpu_setup[i][1])) < 0) {
            snprintf(err, (size_t)errlen, "MPU-6050: write 0x%02x failed (%s)", mpu_setup[i][0], strerror(-r));
            return -1;
        }
        if (i == 0)
            pause_ms(100);
    }
    return 0;
}

static int16_t be16(const uint8_t *b) { return (int16_t)(b[0] << 8 | b[1]); }

int mpu_read(int fd, int addr, vec3 *acc, vec3 *gyro)
{
    uint8_t b[14];
    int r = rregs(fd, addr, 0x3B, b, 14);
    if (r < 0)
        return r;
    real ka = FC_G0 / ACC_LSB_PER_G, kg = (M_PI / 180.0) / GYRO_LSB_PER_DPS;
    *acc = v3(be16(b) * ka, be16(b + 2) * ka, be16(b + 4) * ka);
    *gyro = v3(be16(b + 8) * kg, be16(b + 10) * kg, be16(b + 12) * kg);
    return 0;
}

int hmc_init(int fd, int addr, char *err, int errlen)
{
    uint8_t id[3] = { 0 };
    int r = rregs(fd, addr, 0x0A, id, 3);
    if (r < 0) {
        snprintf(err, (size_t)errlen, "HMC5883L: no answer at 0x%02x (%s)", addr, strerror(-r));
        return -1;
    }
    if (memcmp(id, "H43", 3) != 0) {
        snprintf(err, (size_t)errlen, "HMC5883L: wrong ID %02x %02x %02x at 0x%02x (expected 'H43')", id[0], id[1],
                 id[2], addr);
        return -1;
    }
    if (wreg(fd, addr, 0x00, 0x18) < 0 || wreg(fd, addr, 0x01, 0x20) < 0 || wreg(fd, addr, 0x02, 0x00) < 0) {
        snprintf(err, (size_t)errlen, "HMC5883L: configuration writes failed");
        return -1;
    }
    return 0;
}

int hmc_read(int fd, int addr, vec3 *field)
{
    uint8_t b[6];
    int r = rregs(fd, addr, 0x03, b, 6);
    if (r < 0)
        return r;
    const real k = 1.0 / 1090.0; /* gain 1, gauss per LSB; data order X, Z, Y */
    *field = v3(be16(b) * k, be16(b + 4) * k, be16(b + 2) * k);
    return 0;
}

int ms5611_init(int fd, int addr, ms5611_dev *d, char *err, int errlen)
{
    memset(d, 0, sizeof *d);
    uint8_t cmd = 0x1E;
    int r = i2c_xfer(fd, addr, &cmd, 1, NULL, 0);
    if (r < 0) {
        snprintf(err, (size_t)errlen, "MS5611: no answer at 0x%02x (%s)", addr, strerror(-r));
        return -1;
    }
    pause_ms(3);
    int nonzero = 0;
    for (int i = 0; i < 8; i++) {
        uint8_t b[2];
        if ((r = rregs(fd, addr, (uint8_t)(0xA0 + 2 * i), b, 2)) < 0) {
            snprintf(err, (size_t)errlen, "MS5611: PROM read failed (%s)", strerror(-r));
            return -1;
        }
        d->prom[i] = (uint16_t)(b[0] << 8 | b[1]);
        nonzero |= d->prom[i];
    }
    unsigned crc = ms5611_crc4(d->prom);
    if (!nonzero || crc != (d->prom[7] & 0xF)) {
        snprintf(err, (size_t)errlen, "MS5611: PROM CRC-4 mismatch (computed 0x%x, stored 0x%x)", crc,
                 d->prom[7] & 0xF);
        return -1;
    }
    return 0;
}

static int target_xfer(void *ctx, const uint8_t *w, int wn, uint8_t *r, int rn)
{
    i2c_target *t = ctx;
    return i2c_xfer(t->fd, t->addr, w, wn, r, rn);
}

static double monotonic_s(void *ctx)
{
    (void)ctx;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

ms5611_bus ms5611_on_i2c(i2c_target *target) { return (ms5611_bus){ target_xfer, monotonic_s, target }; }

static int put(const char *path, const char *value)
{
    int fd = open(path, O_WRONLY | O_CLOEXEC);
    if (fd < 0)
        return -errno;
    ssize_t n = write(fd, value, strlen(value));
    int e = n < 0 ? -errno : 0;
    close(fd);
    return e;
}

int pwm_setup(int chip, int channels, long period_ns, char *err, int errlen)
{
    char path[128], v[32];
    for (int ch = 0; ch < channels; ch++) {
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip%d/export", chip);
        snprintf(v, sizeof v, "%d", ch);
        int r = put(path, v);
        if (r < 0 && r != -EBUSY) { /* already exported is fine */
            snprintf(err, (size_t)errlen, "PWM: cannot export channel %d of pwmchip%d (%s)", ch, chip, strerror(-r));
            return -1;
        }
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip%d/pwm%d/period", chip, ch);
        snprintf(v, sizeof v, "%ld", period_ns);
        if ((r = put(path, v)) < 0 || (r = pwm_write_us(chip, ch, 1000.0)) < 0) {
            snprintf(err, (size_t)errlen, "PWM: cannot set channel %d (%s)", ch, strerror(-r));
            return -1;
        }
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip%d/pwm%d/enable", chip, ch);
        if ((r = put(path, "1")) < 0) {
            snprintf(err, (size_t)errlen, "PWM: cannot enable channel %d (%s)", ch, strerror(-r));
            return -1;
        }
    }
    return 0;
}

/* duty_cycle files, opened on first use and kept (fd + 1; 0: not open), as a driver does: the loop writes
   four per cycle, and an open and a close around each write would cost as many syscalls again. */
#define PWM_FDS 16
static int duty_fd[PWM_FDS], duty_chip[PWM_FDS];

int pwm_write_us(int chip, int channel, double us)
{
    char v[32];
    int len = snprintf(v, sizeof v, "%ld", (long)(clampd(us, 1000.0, 2000.0) * 1000.0));
    if (channel < 0 || channel >= PWM_FDS)
        return -EINVAL;
    if (duty_fd[channel] && duty_chip[channel] != chip) {
        close(duty_fd[channel] - 1);
        duty_fd[channel] = 0;
    }
    if (!duty_fd[channel]) {
        char path[128];
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip%d/pwm%d/duty_cycle", chip, channel);
        int fd = open(path, O_WRONLY | O_CLOEXEC);
        if (fd < 0)
            return -errno;
        duty_fd[channel] = fd + 1;
        duty_chip[channel] = chip;
    }
    return pwrite(duty_fd[channel] - 1, v, (size_t)len, 0) < 0 ? -errno : 0;
}
