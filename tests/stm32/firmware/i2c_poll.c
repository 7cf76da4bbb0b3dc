/* The I2C test firmware driving I2C1 by polling, with the sequences of ST's HAL (HAL_I2C_Mem_Read and
   _Write of the STM32F4 HAL: 1 byte with ACK cleared before ADDR is, 2 bytes with POS, N bytes with the
   last three taken at BTF), at 400 kHz (fast mode). Besides i2c_checks.h's transfers it reports the
   status registers at the first START and address of each direction. */
#include "i2c_hal_poll.h"

#define SCL_PIN I2C1_SCL_PIN
#define SDA_PIN I2C1_SDA_PIN
#define I2C_PINS I2C1_PINS

/* A burst read left after two bytes: the controller reset in the middle, as by a watchdog, no STOP */
static void abandon_a_read(void)
{
    const uint8_t first = MPU_ACCEL_XOUT_H;
    uint8_t bytes[2];
    wait_bus_free();
    I2C1_CR1 &= ~I2C_CR1_POS;
    address(MPU_ADDR << 1);
    clear_addr(&sr1_addr_write, &sr2_addr_write);
    wait_sr1(I2C_SR1_TXE, "stuck_txe_abandon");
    I2C1_DR = first;
    wait_sr1(I2C_SR1_BTF, "stuck_btf_abandon");
    I2C1_CR1 |= I2C_CR1_ACK;
    address(MPU_ADDR << 1 | 1u);
    clear_addr(&sr1_addr_read, &sr2_addr_read);
    for (unsigned i = 0; i < 2; i++) {
        wait_sr1(I2C_SR1_RXNE, "stuck_rxne_abandon");
        bytes[i] = (uint8_t)I2C1_DR;
    }
    report("abandoned_bytes", big_endian(bytes, 2));
    I2C1_CR1 = I2C_CR1_SWRST;
    report("cr1_in_reset", I2C1_CR1);
    report("cr2_in_reset", I2C1_CR2);
    report("trise_in_reset", I2C1_TRISE);
    I2C1_CR1 = 0;
}

/* INAV's bus unstick (i2cUnstick): SCL and SDA as open-drain outputs, released; nine SCL pulses; then a
   STOP made by hand (SDA low, SCL high, SDA high); then the pins back to I2C1 */
static void unstick(void)
{
    GPIO_BSRR(PORT_B) = I2C_PINS;
    GPIO_MODER(PORT_B) = (GPIO_MODER(PORT_B) & ~(0xFu << I2C1_MODER_SHIFT)) | (0x5u << I2C1_MODER_SHIFT);
    report("sr2_stuck", I2C1_SR2);
    report("idr_stuck", GPIO_IDR(PORT_B) & I2C_PINS);
    for (unsigned pulse = 0; pulse < 9; pulse++) {
        GPIO_BSRR(PORT_B) = 1u << (SCL_PIN + 16);
        GPIO_BSRR(PORT_B) = 1u << SCL_PIN;
    }
    report("idr_after_pulses", GPIO_IDR(PORT_B) & I2C_PINS);
    GPIO_BSRR(PORT_B) = 1u << (SDA_PIN + 16);
    report("sr2_sda_low", I2C1_SR2);
    GPIO_BSRR(PORT_B) = 1u << SDA_PIN; /* SDA rises with SCL high: STOP */
    report("sr2_after_stop", I2C1_SR2);
    GPIO_MODER(PORT_B) = (GPIO_MODER(PORT_B) & ~(0xFu << I2C1_MODER_SHIFT)) | (0xAu << I2C1_MODER_SHIFT);
}

int main(void)
{
    i2c1_init(I2C_CCR_FS | 14u, 6u); /* 16 MHz / (3 * 14): 381 kHz; 300 ns rise: 16 * 0.3 + 1 */
    run_checks();
    report("sr1_start", sr1_start);
    report("sr1_addr_write", sr1_addr_write);
    report("sr2_addr_write", sr2_addr_write);
    report("sr1_addr_read", sr1_addr_read);
    report("sr2_addr_read", sr2_addr_read);

    abandon_a_read();
    i2c1_init(I2C_CCR_FS | 14u, 6u);
    report("sr2_after_reset", I2C1_SR2);
    unstick();
    report("who_am_i_after_unstick", read_reg(MPU_ADDR, MPU_WHO_AM_I));
    put_text("done\n");
    return 0;
}
