/* ST's HAL polling sequences on I2C1 (HAL_I2C_Mem_Read and _Write of the STM32F4 HAL: 1 byte with ACK
   cleared before ADDR is, 2 bytes with POS, N bytes with the last three taken at BTF): xfer() for
   i2c_checks.h, shared by the I2C test firmware (i2c_poll.c), the hover firmware (hover_rate.c) and the
   trace replayer (i2c_replay.c, which probes an address alone with probe()). The
   status registers at the first START and address of each direction are kept for the reports. */
#ifndef I2C_HAL_POLL_H
#define I2C_HAL_POLL_H

#include "i2c_checks.h"

/* Waits for any of @mask in SR1 (or AF); the run ends naming @what when it never comes */
static uint32_t wait_sr1(uint32_t mask, const char *what)
{
    for (uint32_t i = 0; i < POLL_LIMIT; i++) {
        uint32_t sr1 = I2C1_SR1;
        if (sr1 & (mask | I2C_SR1_AF)) {
            return sr1;
        }
    }
    report(what, I2C1_SR1);
    exit_with(4);
    return 0;
}

static uint32_t sr1_start, sr1_addr_write, sr2_addr_write, sr1_addr_read, sr2_addr_read;

static void keep_first(uint32_t *slot, uint32_t value)
{
    if (*slot == 0) {
        *slot = value;
    }
}

/* START, then the address byte: 0, or -1 (STOP sent, AF cleared) on a NACK. ADDR is left set. */
static int address(uint8_t byte)
{
    I2C1_CR1 |= I2C_CR1_START;
    keep_first(&sr1_start, wait_sr1(I2C_SR1_SB, "stuck_sb"));
    I2C1_DR = byte; /* SR1 read, then DR written: SB clears */
    uint32_t sr1 = wait_sr1(I2C_SR1_ADDR, "stuck_addr");
    if (sr1 & I2C_SR1_AF) {
        I2C1_CR1 |= I2C_CR1_STOP;
        I2C1_SR1 = ~I2C_SR1_AF;
        nack_sr1 = sr1;
        nacks++;
        return -1;
    }
    return 0;
}

/* SR1 read, then SR2 read: ADDR clears */
static uint32_t clear_addr(uint32_t *sr1_slot, uint32_t *sr2_slot)
{
    uint32_t sr1 = I2C1_SR1;
    uint32_t sr2 = I2C1_SR2;
    keep_first(sr1_slot, sr1);
    keep_first(sr2_slot, sr2);
    return sr2;
}

static void receive(uint8_t *rx, unsigned n)
{
    if (n == 1) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        clear_addr(&sr1_addr_read, &sr2_addr_read);
        I2C1_CR1 |= I2C_CR1_STOP;
        wait_sr1(I2C_SR1_RXNE, "stuck_rxne_1");
        rx[0] = (uint8_t)I2C1_DR;
    } else if (n == 2) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        I2C1_CR1 |= I2C_CR1_POS;
        clear_addr(&sr1_addr_read, &sr2_addr_read);
        wait_sr1(I2C_SR1_BTF, "stuck_btf_2");
        I2C1_CR1 |= I2C_CR1_STOP;
        rx[0] = (uint8_t)I2C1_DR;
        rx[1] = (uint8_t)I2C1_DR;
    } else {
        unsigned i = 0;
        clear_addr(&sr1_addr_read, &sr2_addr_read);
        while (n - i > 3) {
            wait_sr1(I2C_SR1_RXNE, "stuck_rxne_n");
            rx[i++] = (uint8_t)I2C1_DR;
        }
        wait_sr1(I2C_SR1_BTF, "stuck_btf_n3"); /* N-2 in DR, N-1 in the shift register */
        I2C1_CR1 &= ~I2C_CR1_ACK;
        rx[i++] = (uint8_t)I2C1_DR; /* N comes in, NACKed */
        wait_sr1(I2C_SR1_BTF, "stuck_btf_n2");
        I2C1_CR1 |= I2C_CR1_STOP;
        rx[i++] = (uint8_t)I2C1_DR;
        rx[i++] = (uint8_t)I2C1_DR;
    }
}

/* HAL_I2C_IsDeviceReady's one attempt: the address alone, as a write; STOP, then ADDR cleared. 0, or -1
   on a NACK */
static inline int probe(uint8_t addr)
{
    wait_bus_free();
    I2C1_CR1 &= ~I2C_CR1_POS;
    if (address((uint8_t)(addr << 1)) != 0) {
        return -1;
    }
    I2C1_CR1 |= I2C_CR1_STOP;
    clear_addr(&sr1_addr_write, &sr2_addr_write);
    return 0;
}

static int xfer(uint8_t addr, const uint8_t *tx, unsigned n_tx, uint8_t *rx, unsigned n_rx)
{
    wait_bus_free();
    I2C1_CR1 &= ~I2C_CR1_POS;
    if (n_tx > 0) {
        if (address((uint8_t)(addr << 1)) != 0) {
            return -1;
        }
        clear_addr(&sr1_addr_write, &sr2_addr_write);
        for (unsigned i = 0; i < n_tx; i++) {
            wait_sr1(I2C_SR1_TXE, "stuck_txe");
            I2C1_DR = tx[i];
        }
        wait_sr1(I2C_SR1_BTF, "stuck_btf_write");
        if (n_rx == 0) {
            I2C1_CR1 |= I2C_CR1_STOP;
            return 0;
        }
    }
    I2C1_CR1 |= I2C_CR1_ACK;
    if (address((uint8_t)(addr << 1 | 1u)) != 0) {
        return -1;
    }
    receive(rx, n_rx);
    return 0;
}

#endif
