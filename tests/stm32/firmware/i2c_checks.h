/* What the STM32 tier's I2C test firmwares (i2c_poll.c, i2c_irq.c) do on I2C1 with the GY-86 on it, the
   same transfers and reports whichever way the firmware drives the controller. The firmware defines
   xfer() (write n_tx bytes, then with a repeated START read n_rx bytes, then STOP; 0, or -1 when the
   address was not acknowledged) and counts NACKs in nacks; tests/stm32/test_i2c.py judges the reports
   against the sensors' datasheets (docs/sensors.md). */
#ifndef I2C_CHECKS_H
#define I2C_CHECKS_H

#include "semihost.h"
#include "stm32f405.h"
#include <stdint.h>

#define MPU_ADDR 0x68u
#define HMC_ADDR 0x1Eu
#define BARO_ADDR 0x77u
#define ABSENT_ADDR 0x50u
#define MPU_ACCEL_XOUT_H 0x3Bu
#define MPU_INT_PIN_CFG 0x37u
#define MPU_INT_PIN_CFG_I2C_BYPASS_EN 0x02u
#define MPU_PWR_MGMT_1 0x6Bu
#define MPU_WHO_AM_I 0x75u
#define HMC_ID_A 0x0Au
#define BARO_PROM_READ 0xA0u
#define APB1_MHZ 16u /* HSI, no prescaler: the clock at reset */
/* a safety net against a flag that never comes (the test then fails naming it): not a time */
#define POLL_LIMIT 1000000u

static int xfer(uint8_t addr, const uint8_t *tx, unsigned n_tx, uint8_t *rx, unsigned n_rx);
static uint32_t nacks __attribute__((unused));
static uint32_t nack_sr1 __attribute__((unused)); /* SR1 as the firmware found it at the last NACK */

/* I2C1's pins, alternate function 4 (RM0090 / the F405 datasheet's table 9): PB6 (SCL) and PB7 (SDA), or
   PB8 and PB9 when built with -DI2C1_SCL_PIN=8u (as on the Black Pill) */
#ifndef I2C1_SCL_PIN
#define I2C1_SCL_PIN 6u
#endif
#define I2C1_SDA_PIN (I2C1_SCL_PIN + 1u)
#define I2C1_PINS ((1u << I2C1_SCL_PIN) | (1u << I2C1_SDA_PIN))
#define I2C1_MODER_SHIFT (2u * I2C1_SCL_PIN)
#define I2C1_AFR REG(GPIO_BASE(PORT_B) + 0x20u + 4u * (I2C1_SCL_PIN / 8u)) /* AFRL or AFRH */
#define I2C1_AF4_BOTH (0x44u << (4u * (I2C1_SCL_PIN % 8u)))

/* I2C1 on its two pins, alternate function 4, open drain with pull-ups, as a board has it; then a
   software reset and the timing for @ccr (SCL) and @trise */
static inline void i2c1_init(uint32_t ccr, uint32_t trise)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOBEN;
    RCC_APB1ENR |= RCC_APB1ENR_I2C1EN;
    GPIO_MODER(PORT_B) = (GPIO_MODER(PORT_B) & ~(0xFu << I2C1_MODER_SHIFT)) | (0xAu << I2C1_MODER_SHIFT);
    GPIO_OTYPER(PORT_B) |= I2C1_PINS;
    GPIO_PUPDR(PORT_B) = (GPIO_PUPDR(PORT_B) & ~(0xFu << I2C1_MODER_SHIFT)) | (0x5u << I2C1_MODER_SHIFT);
    I2C1_AFR = (I2C1_AFR & ~(0xFFu << (4u * (I2C1_SCL_PIN % 8u)))) | I2C1_AF4_BOTH;
    I2C1_CR1 = I2C_CR1_SWRST;
    I2C1_CR1 = 0;
    I2C1_CR2 = APB1_MHZ;
    I2C1_OAR1 = 1u << 14; /* RM0090 27.6.3: bit 14 kept at 1 by software */
    I2C1_CCR = ccr;
    I2C1_TRISE = trise;
    I2C1_CR1 = I2C_CR1_PE;
}

static inline void wait_bus_free(void)
{
    for (uint32_t i = 0; i < POLL_LIMIT; i++) {
        if (!(I2C1_SR2 & I2C_SR2_BUSY)) {
            return;
        }
    }
    report("stuck_busy_sr2", I2C1_SR2);
    exit_with(4);
}

static inline uint32_t read_reg(uint8_t addr, uint8_t reg)
{
    uint8_t value = 0;
    return xfer(addr, &reg, 1, &value, 1) == 0 ? value : 0xFFFFFFFFu;
}

static inline void write_reg(uint8_t addr, uint8_t reg, uint8_t value)
{
    const uint8_t bytes[2] = { reg, value };
    if (xfer(addr, bytes, 2, 0, 0) != 0) {
        report("write_nack", reg);
    }
}

/* The MS5611's PROM check, as its application note AN520 computes it: CRC-4 over the eight words with
   the CRC's own nibble (word 7's low four bits) taken as 0 */
static inline uint32_t ms5611_crc4(const uint16_t prom[8])
{
    uint32_t rem = 0;
    for (unsigned n = 0; n < 16; n++) {
        uint16_t word = n == 15 ? (uint16_t)(prom[7] & 0xFF00u) : prom[n >> 1];
        rem ^= (n & 1u) ? (word & 0xFFu) : (uint32_t)(word >> 8);
        for (unsigned bit = 0; bit < 8; bit++) {
            rem = (rem & 0x8000u) ? ((rem << 1) ^ 0x3000u) : (rem << 1);
        }
    }
    return (rem >> 12) & 0xFu;
}

static inline uint32_t big_endian(const uint8_t *bytes, unsigned n)
{
    uint32_t value = 0;
    for (unsigned i = 0; i < n; i++) {
        value = value << 8 | bytes[i];
    }
    return value;
}

static inline void run_checks(void)
{
    report("who_am_i", read_reg(MPU_ADDR, MPU_WHO_AM_I)); /* 1 byte */
    report("pwr_mgmt_1_reset", read_reg(MPU_ADDR, MPU_PWR_MGMT_1));

    uint8_t id[3] = { 0, 0, 0 };
    const uint8_t id_reg = HMC_ID_A;
    report("hmc_before_bypass", (uint32_t)xfer(HMC_ADDR, &id_reg, 1, id, 3));
    write_reg(MPU_ADDR, MPU_PWR_MGMT_1, 0x00); /* awake, internal oscillator */
    write_reg(MPU_ADDR, MPU_INT_PIN_CFG, MPU_INT_PIN_CFG_I2C_BYPASS_EN);
    report("pwr_mgmt_1_awake", read_reg(MPU_ADDR, MPU_PWR_MGMT_1));
    report("int_pin_cfg", read_reg(MPU_ADDR, MPU_INT_PIN_CFG));
    report("hmc_after_bypass", (uint32_t)xfer(HMC_ADDR, &id_reg, 1, id, 3)); /* 3 bytes */
    report("hmc_id", big_endian(id, 3));

    uint16_t prom[8];
    for (unsigned k = 0; k < 8; k++) { /* command, STOP, then 2 bytes (HAL's POS sequence) */
        const uint8_t command = (uint8_t)(BARO_PROM_READ + 2u * k);
        uint8_t word[2] = { 0, 0 };
        if (xfer(BARO_ADDR, &command, 1, 0, 0) != 0 || xfer(BARO_ADDR, 0, 0, word, 2) != 0) {
            report("prom_nack", k);
        }
        prom[k] = (uint16_t)big_endian(word, 2);
        char name[] = "prom0";
        name[4] = (char)('0' + k);
        report(name, prom[k]);
    }
    report("prom_crc4", ms5611_crc4(prom));

    uint8_t burst[14];
    const uint8_t first = MPU_ACCEL_XOUT_H;
    report("burst_result", (uint32_t)xfer(MPU_ADDR, &first, 1, burst, sizeof burst)); /* N bytes */
    report("burst_0", big_endian(burst, 4));
    report("burst_1", big_endian(burst + 4, 4));
    report("burst_2", big_endian(burst + 8, 4));
    report("burst_3", big_endian(burst + 12, 2));

    const uint8_t nothing[2] = { 0x00, 0x11 };
    report("absent_result", (uint32_t)xfer(ABSENT_ADDR, nothing, 2, 0, 0));
    report("absent_sr1", nack_sr1);
    report("who_am_i_after_nack", read_reg(MPU_ADDR, MPU_WHO_AM_I));
    report("nacks", nacks);
    wait_bus_free();
    report("sr2_end", I2C1_SR2);
}

#endif
