/* Device access as a Linux board does it: /dev/i2c-N ioctls, sysfs PWM, a serial port. */
#ifndef DRIVERS_H
#define DRIVERS_H

#include <stdint.h>

#include "fc.h"

int i2c_open(const char *path);
/* write wn bytes then (repeated START) read rn bytes; 0 or -errno */
int i2c_xfer(int fd, int addr, const uint8_t *w, int wn, uint8_t *r, int rn);

/* Each init returns 0, or -1 with a message in err. */
int mpu_init(int fd, int addr, char *err, int errlen);
int mpu_read(int fd, int addr, vec3 *acc_mps2, vec3 *gyro_rads); /* sensor frame */
int hmc_init(int fd, int addr, char *err, int errlen);
int hmc_read(int fd, int addr, vec3 *field_gauss);
int ms5611_init(int fd, int addr, ms5611_dev *d, char *err, int errlen);
/* The MS5611 at addr on an open i2c-dev fd, for ms5611_poll (the struct must outlive the calls). */
typedef struct {
    int fd, addr;
} i2c_target;
ms5611_bus ms5611_on_i2c(i2c_target *target);

int pwm_setup(int chip, int channels, long period_ns, char *err, int errlen);
int pwm_write_us(int chip, int channel, double us);

#endif
