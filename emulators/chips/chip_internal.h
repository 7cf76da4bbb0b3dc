/* Between the chip core's files: each chip's bus side and time, and the board's helpers. */
#ifndef CHIP_INTERNAL_H
#define CHIP_INTERNAL_H

#include <string.h>

#include "chip_core.h"
#include "chip_registers.h"

/* MPU-6050 register addresses used by the core */
#define MPU_SMPLRT_DIV 0x19
#define MPU_CONFIG 0x1A
#define MPU_GYRO_CONFIG 0x1B
#define MPU_ACCEL_CONFIG 0x1C
#define MPU_FIFO_EN 0x23
#define MPU_I2C_SLV0_ADDR 0x25
#define MPU_I2C_MST_STATUS 0x36
#define MPU_INT_PIN_CFG 0x37
#define MPU_INT_STATUS 0x3A
#define MPU_TEMP_OUT_H 0x41
#define MPU_GYRO_XOUT_H 0x43
#define MPU_EXT_SENS_DATA_00 0x49
#define MPU_I2C_SLV0_DO 0x63
#define MPU_USER_CTRL 0x6A
#define MPU_PWR_MGMT_1 0x6B
#define MPU_PWR_MGMT_2 0x6C
#define MPU_FIFO_COUNT_H 0x72
#define MPU_FIFO_COUNT_L 0x73
#define MPU_FIFO_R_W 0x74
#define MPU_WHO_AM_I 0x75

/* HMC5883L */
#define HMC_CRA 0x00
#define HMC_CRB 0x01
#define HMC_MODE 0x02
#define HMC_DATA 0x03
#define HMC_STATUS 0x09

/* a sample instant's choice from a queue: true when a new sample valid at or before t was taken */
bool chip_take_imu(chip_mpu *m, uint64_t t_ns);
bool chip_take_mag(chip_hmc *h, uint64_t t_ns);
bool chip_take_baro(chip_baro *s, uint64_t t_ns);
uint64_t chip_splitmix64(uint64_t *state);
bool chip_fault_active(const chip_board *b, uint8_t chip, uint8_t kind, uint64_t t_ns);

void mpu_reset(chip_mpu *m);
bool mpu_advance(chip_board *b, uint64_t now_ns, chip_need *need);
void mpu_prepare(chip_mpu *m);
/* the held sample (zeros at power-on) encoded under the present configuration, so the first instants
 * copy it: called where encoding costs nothing (chip_board_init, outside any interrupt) */
void mpu_prime(chip_mpu *m);
void mpu_start(chip_mpu *m, bool read);
void mpu_write(chip_board *b, uint8_t byte);
uint8_t mpu_read(chip_mpu *m);
void mpu_stop(chip_mpu *m);
bool mpu_bypass(const chip_mpu *m);

void hmc_reset(chip_hmc *h);
void hmc_prime(chip_hmc *h); /* as mpu_prime: the held field encoded at the effective gain */
bool hmc_advance(chip_board *b, uint64_t now_thirds, chip_need *need);
void hmc_prepare(chip_hmc *h);
void hmc_start(chip_hmc *h, bool read);
void hmc_write(chip_hmc *h, uint8_t byte, bool from_aux);
uint8_t hmc_read(chip_hmc *h);

void baro_reset(chip_baro *s);
bool baro_advance(chip_board *b, uint64_t now_ns, chip_need *need);
void baro_start(chip_baro *s, bool read);
void baro_write(chip_baro *s, uint8_t byte);
uint8_t baro_read(chip_baro *s);

#endif
