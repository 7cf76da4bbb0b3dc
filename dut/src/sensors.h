/* The GY-86's chips as the usual set-up runs them: the MPU-6050 woken, DLPF 44 Hz, +-2000 dps, +-4 g;
   the HMC5883L configured through the MPU's bypass, then read by the MPU's aux master (SLV0 copies its
   six data bytes into EXT_SENS_DATA), so one burst from the MPU gives all three vectors; the MS5611's
   PROM read and CRC-4 checked, its conversions run by the portable state machine (ms5611_poll). Same
   units, frames and scales as the Linux drivers (dut/linux/drivers.c). */
#ifndef SENSORS_H
#define SENSORS_H

#include "fc.h"

#define SENSORS_MPU 0x68
#define SENSORS_HMC 0x1E
#define SENSORS_BARO 0x77

/* 0, or a negative step number (the telemetry says which: sensors_why) */
int sensors_init(uint8_t mpu, uint8_t hmc, uint8_t baro, ms5611_dev *d, void (*each)(void));
const char *sensors_why(int code);
/* One burst: acc (m/s^2), gyro (rad/s), mag (gauss), sensor frame. *mag_ok: the aux master read the
   HMC5883L without a NACK since the last call. 0, or negative on a bus error. */
int sensors_read(uint8_t mpu, vec3 *acc, vec3 *gyro, vec3 *mag, int *mag_ok);
ms5611_bus sensors_baro_bus(uint8_t *addr);

#endif
