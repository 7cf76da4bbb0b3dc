/* The I2C test firmware driving I2C1 from its event and error interrupts (NVIC lines 31 and 32), the
   way the SPL's interrupt-driven drivers and Linux's i2c-stm32f4 do: SB -> address, ADDR -> ACK/POS
   set-up and clear, TXE -> next byte, BTF -> repeated START or STOP, RXNE -> bytes while more than three
   remain, then the last three at BTF (two at BTF with POS, one at RXNE); AF on the error line -> STOP.
   At 100 kHz (standard mode). Reports i2c_checks.h's transfers and how many interrupts each line took. */
#include "i2c_checks.h"

#define ALL_INTERRUPTS (I2C_CR2_ITEVTEN | I2C_CR2_ITBUFEN | I2C_CR2_ITERREN)
#define RUNNING 1

static struct {
    uint8_t addr;
    const uint8_t *tx;
    unsigned n_tx, i_tx;
    uint8_t *rx;
    unsigned n_rx, i_rx;
    int reading;
    int addressed;       /* the read's ADDR handled: BTF from here on is the receiver's */
    volatile int result; /* RUNNING, then 0 or -1 (NACK) */
} t;
static volatile uint32_t ev_interrupts, er_interrupts;

static void finish(int result)
{
    I2C1_CR2 &= ~ALL_INTERRUPTS;
    t.result = result;
}

static void on_address(void)
{
    uint32_t sr2;
    if (!t.reading) {
        sr2 = I2C1_SR2; /* ADDR clears; TXE follows */
        I2C1_CR2 |= I2C_CR2_ITBUFEN;
        return;
    }
    t.addressed = 1;
    if (t.n_rx == 1) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        sr2 = I2C1_SR2;
        I2C1_CR1 |= I2C_CR1_STOP;
        I2C1_CR2 |= I2C_CR2_ITBUFEN;
    } else if (t.n_rx == 2) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        I2C1_CR1 |= I2C_CR1_POS;
        sr2 = I2C1_SR2;
        I2C1_CR2 &= ~I2C_CR2_ITBUFEN; /* both bytes at BTF */
    } else {
        sr2 = I2C1_SR2;
        if (t.n_rx > 3) {
            I2C1_CR2 |= I2C_CR2_ITBUFEN;
        }
    }
    (void)sr2;
}

static void on_transmit(uint32_t sr1)
{
    if ((sr1 & I2C_SR1_TXE) && t.i_tx < t.n_tx) {
        I2C1_DR = t.tx[t.i_tx++];
        if (t.i_tx == t.n_tx) {
            I2C1_CR2 &= ~I2C_CR2_ITBUFEN; /* the end comes as BTF */
        }
    } else if ((sr1 & I2C_SR1_BTF) && !(I2C1_CR1 & I2C_CR1_START)) {
        if (t.n_rx > 0) {
            t.reading = 1;
            I2C1_CR1 = (I2C1_CR1 & ~I2C_CR1_POS) | I2C_CR1_ACK | I2C_CR1_START;
        } else {
            I2C1_CR1 |= I2C_CR1_STOP;
            finish(0);
        }
    }
}

static void on_receive(uint32_t sr1)
{
    unsigned left = t.n_rx - t.i_rx;
    if (t.n_rx == 1 && (sr1 & I2C_SR1_RXNE)) {
        t.rx[t.i_rx++] = (uint8_t)I2C1_DR;
        finish(0);
    } else if ((sr1 & I2C_SR1_RXNE) && left > 3 && (I2C1_CR2 & I2C_CR2_ITBUFEN)) {
        t.rx[t.i_rx++] = (uint8_t)I2C1_DR;
        if (left - 1 == 3) {
            I2C1_CR2 &= ~I2C_CR2_ITBUFEN; /* the last three at BTF */
        }
    } else if ((sr1 & I2C_SR1_BTF) && left == 3) {
        I2C1_CR1 &= ~I2C_CR1_ACK;
        t.rx[t.i_rx++] = (uint8_t)I2C1_DR;
    } else if ((sr1 & I2C_SR1_BTF) && left == 2) {
        I2C1_CR1 |= I2C_CR1_STOP;
        t.rx[t.i_rx++] = (uint8_t)I2C1_DR;
        t.rx[t.i_rx++] = (uint8_t)I2C1_DR;
        finish(0);
    }
}

void i2c1_ev_handler(void)
{
    ev_interrupts++;
    uint32_t sr1 = I2C1_SR1;
    if (sr1 & I2C_SR1_SB) {
        I2C1_DR = (uint32_t)(t.addr << 1) | (t.reading ? 1u : 0u);
    } else if (sr1 & I2C_SR1_ADDR) {
        on_address();
    } else if (!t.reading) {
        on_transmit(sr1);
    } else if (t.addressed) { /* (the transmitter's BTF stays until the repeated START is out) */
        on_receive(sr1);
    }
}

void i2c1_er_handler(void)
{
    er_interrupts++;
    uint32_t sr1 = I2C1_SR1;
    if (sr1 & I2C_SR1_AF) {
        I2C1_SR1 = ~I2C_SR1_AF;
        I2C1_CR1 |= I2C_CR1_STOP;
        nack_sr1 = sr1;
        nacks++;
        finish(-1);
    }
}

static int xfer(uint8_t addr, const uint8_t *tx, unsigned n_tx, uint8_t *rx, unsigned n_rx)
{
    wait_bus_free();
    t.addr = addr;
    t.tx = tx;
    t.n_tx = n_tx;
    t.i_tx = 0;
    t.rx = rx;
    t.n_rx = n_rx;
    t.i_rx = 0;
    t.reading = n_tx == 0;
    t.addressed = 0;
    t.result = RUNNING;
    I2C1_CR2 |= I2C_CR2_ITEVTEN | I2C_CR2_ITERREN;
    I2C1_CR1 = (I2C1_CR1 & ~I2C_CR1_POS) | I2C_CR1_ACK | I2C_CR1_START;
    for (uint32_t i = 0; t.result == RUNNING; i++) {
        if (i == POLL_LIMIT) {
            report("stuck_irq_sr1", I2C1_SR1);
            exit_with(4);
        }
    }
    return t.result;
}

int main(void)
{
    NVIC_ISER(0) = 1u << I2C1_EV_IRQ;
    NVIC_ISER(1) = 1u << (I2C1_ER_IRQ - 32u);
    i2c1_init(80u, 17u); /* 16 MHz / (2 * 80): 100 kHz; 1000 ns rise: 16 + 1 */
    run_checks();
    report("ev_interrupts", ev_interrupts);
    report("er_interrupts", er_interrupts);
    put_text("done\n");
    return 0;
}
