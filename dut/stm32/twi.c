/* I2C1 by polling (twi.h), RM0090 27.3.3 and 27.6 (the controller's events and its clear sequences). */
#include "twi.h"

#include "board.h"
#include "clock.h"
#include "stm32f405.h"

#define I2C_SR1_BERR (1u << 8)
#define I2C_SR1_ARLO (1u << 9)
/* a safety net against a flag that never comes: a 9-byte transfer at 400 kHz is ~250 us, and each poll
   about a microsecond (POLL_GAP); 20000 polls are 20 ms */
#define POLL_LIMIT 20000u
/* spin iterations between two reads of SR1: about a microsecond at 168 MHz, under half an SCL period at
   400 kHz, so an event is seen at most that late (a byte takes 22.5 us). Under QEMU's icount each read
   of a device register ends a translation block: polling back to back read SR1 1.97 M times a simulated
   second and took most of QEMU's CPU time (docs/reference-fc.md, "Speed"); with the gap, 0.17 M. */
#define POLL_GAP 40
/* An event the bus needs some SCL periods for is not polled for until 90 % of them have passed (the
   spin is of no device register): a byte is nine periods, so its wait polls twice or three times, not
   twenty. SCL's period at the fast-mode set-up (RM0090 27.6.8, duty 2: T = 3 CCR / f_PCLK1). */
#define SCL_PERIOD_NS (3000u * I2C_FAST_CCR / I2C_FREQ_MHZ)
#define SPINS_FOR_PERIODS(n) ((n)*SCL_PERIOD_NS * POLL_GAP * 9u / 10u / 1000u)
#define PERIODS_START 1u
#define PERIODS_BYTE 9u

twi_stats twi_counters;

/* the board's pair (board.h): SCL on I2C1_SCL_PIN of port B, SDA on the next */
#define SCL I2C1_SCL_PIN
#define SDA (I2C1_SCL_PIN + 1u)
#define PINS ((1u << SCL) | (1u << SDA))
#define MODER_SHIFT (2u * SCL)

static void pins_i2c(void)
{
    GPIO_OTYPER(PORT_B) |= PINS;
    GPIO_PUPDR(PORT_B) = (GPIO_PUPDR(PORT_B) & ~(0xFu << MODER_SHIFT)) | (0x5u << MODER_SHIFT);
    board_pin_af(PORT_B, SCL, 4);
    board_pin_af(PORT_B, SDA, 4);
}

void twi_init(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOBEN;
    RCC_APB1ENR |= RCC_APB1ENR_I2C1EN;
    pins_i2c();
    I2C1_CR1 = I2C_CR1_SWRST;
    I2C1_CR1 = 0;
    I2C1_CR2 = I2C_FREQ_MHZ;
    I2C1_OAR1 = 1u << 14; /* RM0090 27.6.3: bit 14 kept at 1 by software */
    I2C1_CCR = I2C_CCR_FS | I2C_FAST_CCR;
    I2C1_TRISE = I2C_FAST_TRISE;
    I2C1_CR1 = I2C_CR1_PE;
}

/* the controller off, SCL and SDA as open-drain outputs: nine clocks (a slave mid-byte lets go of SDA),
   a STOP (SDA rising while SCL is high), then the controller again */
void twi_recover(void)
{
    twi_counters.recoveries++;
    I2C1_CR1 = I2C_CR1_SWRST;
    GPIO_ODR(PORT_B) |= PINS;
    GPIO_MODER(PORT_B) = (GPIO_MODER(PORT_B) & ~(0xFu << MODER_SHIFT)) | (0x5u << MODER_SHIFT);
    for (int i = 0; i < 9; i++) {
        GPIO_BSRR(PORT_B) = 1u << (SCL + 16);
        clock_wait_us(5);
        GPIO_BSRR(PORT_B) = 1u << SCL;
        clock_wait_us(5);
    }
    GPIO_BSRR(PORT_B) = 1u << (SDA + 16);
    clock_wait_us(5);
    GPIO_BSRR(PORT_B) = 1u << SDA;
    clock_wait_us(5);
    twi_init();
}

/* any of @mask in SR1, which the bus gives after about @periods of SCL: SR1; an error flag (cleared
   here): -1 NACK, -3 bus error; never: -2 */
static int32_t wait_sr1(uint32_t mask, uint32_t periods)
{
    for (uint32_t k = 0; k < SPINS_FOR_PERIODS(periods); k++)
        __asm volatile("nop");
    for (uint32_t i = 0; i < POLL_LIMIT; i++) {
        for (int k = 0; k < POLL_GAP; k++)
            __asm volatile("nop");
        uint32_t sr1 = I2C1_SR1;
        if (sr1 & I2C_SR1_AF) {
            I2C1_CR1 |= I2C_CR1_STOP;
            I2C1_SR1 = ~I2C_SR1_AF;
            return -1;
        }
        if (sr1 & (I2C_SR1_BERR | I2C_SR1_ARLO)) {
            I2C1_SR1 = ~(I2C_SR1_BERR | I2C_SR1_ARLO);
            return -3;
        }
        if (sr1 & mask)
            return (int32_t)sr1;
    }
    return -2;
}

static void clear_addr(void)
{
    (void)I2C1_SR1;
    (void)I2C1_SR2;
}

/* START, then the address byte; ADDR is left set */
static int address(uint8_t byte)
{
    I2C1_CR1 |= I2C_CR1_START;
    int32_t r = wait_sr1(I2C_SR1_SB, PERIODS_START);
    if (r < 0)
        return (int)r;
    I2C1_DR = byte; /* SR1 read, then DR written: SB clears */
    r = wait_sr1(I2C_SR1_ADDR, PERIODS_BYTE);
    return r < 0 ? (int)r : 0;
}

static int receive(uint8_t *rx, uint8_t n)
{
    int32_t r;
    if (n == 1) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        clear_addr();
        I2C1_CR1 |= I2C_CR1_STOP;
        if ((r = wait_sr1(I2C_SR1_RXNE, PERIODS_BYTE)) < 0)
            return (int)r;
        rx[0] = (uint8_t)I2C1_DR;
    } else if (n == 2) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        I2C1_CR1 |= I2C_CR1_POS;
        clear_addr();
        if ((r = wait_sr1(I2C_SR1_BTF, PERIODS_BYTE)) < 0)
            return (int)r;
        I2C1_CR1 |= I2C_CR1_STOP;
        rx[0] = (uint8_t)I2C1_DR;
        rx[1] = (uint8_t)I2C1_DR;
    } else {
        uint8_t i = 0;
        clear_addr();
        while (n - i > 3) {
            if ((r = wait_sr1(I2C_SR1_RXNE, PERIODS_BYTE)) < 0)
                return (int)r;
            rx[i++] = (uint8_t)I2C1_DR;
        }
        if ((r = wait_sr1(I2C_SR1_BTF, PERIODS_BYTE)) < 0) /* N-2 in DR, N-1 in the shift register */
            return (int)r;
        I2C1_CR1 &= ~I2C_CR1_ACK;
        rx[i++] = (uint8_t)I2C1_DR; /* N comes in, NACKed */
        if ((r = wait_sr1(I2C_SR1_BTF, PERIODS_BYTE)) < 0)
            return (int)r;
        I2C1_CR1 |= I2C_CR1_STOP;
        rx[i++] = (uint8_t)I2C1_DR;
        rx[i++] = (uint8_t)I2C1_DR;
    }
    return 0;
}

static int transfer(uint8_t addr, const uint8_t *w, uint8_t wn, uint8_t *r, uint8_t rn)
{
    uint32_t i = 0;
    while ((I2C1_SR2 & I2C_SR2_BUSY) && ++i < POLL_LIMIT)
        ;
    if (i == POLL_LIMIT)
        return -2;
    I2C1_CR1 &= ~I2C_CR1_POS;
    if (wn > 0) {
        int st = address((uint8_t)(addr << 1));
        if (st < 0)
            return st;
        clear_addr();
        for (uint8_t k = 0; k < wn; k++) {
            /* DR and the shift register take the first two bytes at once */
            int32_t s = wait_sr1(I2C_SR1_TXE, k < 2 ? 0u : PERIODS_BYTE);
            if (s < 0)
                return (int)s;
            I2C1_DR = w[k];
        }
        int32_t s = wait_sr1(I2C_SR1_BTF, PERIODS_BYTE);
        if (s < 0)
            return (int)s;
        if (rn == 0) {
            I2C1_CR1 |= I2C_CR1_STOP;
            return 0;
        }
    }
    I2C1_CR1 |= I2C_CR1_ACK;
    int st = address((uint8_t)(addr << 1 | 1u));
    return st < 0 ? st : receive(r, rn);
}

int twi_xfer(uint8_t addr, const uint8_t *w, uint8_t wn, uint8_t *r, uint8_t rn)
{
    int st = transfer(addr, w, wn, r, rn);
    if (st == -1)
        twi_counters.nacks++;
    else if (st == -2)
        twi_counters.timeouts++;
    else if (st == -3)
        twi_counters.bus_errors++;
    if (st == -2 || st == -3)
        twi_recover();
    return st;
}
