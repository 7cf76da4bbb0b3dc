/* The GY-86's MPU-6050 set-up, one table for every platform (dut/linux/drivers.c over i2c-dev,
 * dut/avr/sensors.c over the TWI): register, value, in order; the platform waits 100 ms after the
 * first (DEVICE_RESET). Bypass is on so the HMC5883L can be configured directly on the main bus. */
#ifndef GY86_H
#define GY86_H

#include <stdint.h>

#define MPU_SETUP_N 8
static const uint8_t mpu_setup[MPU_SETUP_N][2] = {
    { 0x6B, 0x80 }, /* DEVICE_RESET */
    { 0x6B, 0x01 }, /* wake, PLL on gyro X */
    { 0x19, 0x00 }, /* SMPLRT_DIV: 1 kHz with the DLPF */
    { 0x1A, 0x03 }, /* CONFIG: DLPF 44/42 Hz */
    { 0x1B, 0x18 }, /* GYRO_CONFIG: +-2000 dps */
    { 0x1C, 0x08 }, /* ACCEL_CONFIG: +-4 g */
    { 0x6A, 0x00 }, /* USER_CTRL: aux master off */
    { 0x37, 0x02 }, /* INT_PIN_CFG: bypass */
};

#endif
