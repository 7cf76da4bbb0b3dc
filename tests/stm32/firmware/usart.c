/* The USART model (RM0090 section 30) under test, run through the rig's link (the session sends the
   bytes at given times, tests/stm32/test_usart.py): USART1's registers at reset, with all ones written
   and after an RCC reset; UART4's (no synchronous or flow-control bits); the frame times with
   DWT_CYCCNT (8E2 at 100000 baud, OVER8 = 1, USART2 on APB1 at PCLK1 = HCLK / 2); TXE and TC timing;
   a message sent from the TXE interrupt and ended on TC; then, from the RXNE, IDLE and PE interrupts, a
   log of every byte received (SR, DR, CYCCNT) until 20 ms; then the interrupts off, so bytes sent at
   22 ms overrun, and SR, DR, SR read at 25 ms. Everything is reported through semihosting at 26 ms.
   The core runs on the 16 MHz HSI: HCLK = PCLK1 = PCLK2 = 16 MHz unless said. */
#include "semihost.h"
#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))
#define RCC_CFGR REG(0x40023808u)
#define RCC_APB2RSTR REG(0x40023824u)
#define RCC_APB1ENR REG(0x40023840u)
#define RCC_APB2ENR REG(0x40023844u)
#define APB2_USART1 (1u << 4)
#define APB1_USART2 (1u << 17)
#define APB1_UART4 (1u << 19)
#define CFGR_PPRE1_DIV2 (4u << 10)
#define USART1 0x40011000u
#define USART2 0x40004400u
#define UART4 0x40004C00u
#define SR(u) REG((u) + 0x00u)
#define DR(u) REG((u) + 0x04u)
#define BRR(u) REG((u) + 0x08u)
#define CR1(u) REG((u) + 0x0Cu)
#define CR2(u) REG((u) + 0x10u)
#define CR3(u) REG((u) + 0x14u)
#define GTPR(u) REG((u) + 0x18u)
#define SR_PE (1u << 0)
#define SR_ORE (1u << 3)
#define SR_IDLE (1u << 4)
#define SR_RXNE (1u << 5)
#define SR_TC (1u << 6)
#define SR_TXE (1u << 7)
#define CR1_RE (1u << 2)
#define CR1_TE (1u << 3)
#define CR1_IDLEIE (1u << 4)
#define CR1_RXNEIE (1u << 5)
#define CR1_TCIE (1u << 6)
#define CR1_TXEIE (1u << 7)
#define CR1_PEIE (1u << 8)
#define CR1_PCE (1u << 10)
#define CR1_M (1u << 12)
#define CR1_UE (1u << 13)
#define CR1_OVER8 (1u << 15)
#define CR2_STOP_2 (2u << 12)
#define SBUS_CR1 (CR1_UE | CR1_M | CR1_PCE | CR1_TE | CR1_RE) /* 8 data bits + even parity */
#define BRR_100K 160u                                         /* 16 MHz / 100000 (OVER8 = 0: BRR = 16 x USARTDIV) */
#define BRR_115200_OVER8 0x113u                               /* mantissa 17, fraction 3/8: 8 x USARTDIV = 139 */
#define BRR_100K_AT_8MHZ 80u
#define DEMCR REG(0xE000EDFCu)
#define DWT_CTRL REG(0xE0001000u)
#define CYCCNT REG(0xE0001004u)
#define NVIC_ISER1 REG(0xE000E104u)
#define NVIC_ICPR1 REG(0xE000E284u)
#define USART1_LINE (1u << (37 - 32))
#define MS 16000u /* CYCCNT at 16 MHz */
#define LOG 64

static volatile uint32_t log_sr[LOG], log_dr[LOG], log_at[LOG];
static volatile uint32_t n_log, txe_irqs, tc_irqs, tc_at, tx_at;
static volatile uint32_t logging;
static const char message[4] = { 'T', 'X', 'I', 'R' };

void usart1_handler(void)
{
    uint32_t sr = SR(USART1), cr1 = CR1(USART1);
    if ((cr1 & CR1_TXEIE) && (sr & SR_TXE)) {
        txe_irqs++;
        if (tx_at < sizeof message) {
            DR(USART1) = (uint8_t)message[tx_at++]; /* (after the SR read: TC's clear sequence) */
        } else {
            CR1(USART1) = (cr1 & ~CR1_TXEIE) | CR1_TCIE;
        }
    }
    if ((cr1 & CR1_TCIE) && (sr & SR_TC)) {
        tc_irqs++;
        tc_at = CYCCNT;
        CR1(USART1) &= ~CR1_TCIE;
    }
    if (logging && (sr & (SR_RXNE | SR_ORE | SR_IDLE | SR_PE))) {
        uint32_t dr = DR(USART1); /* the second half of the clear sequence of PE, FE, NF, ORE and IDLE */
        if (n_log < LOG) {
            log_sr[n_log] = sr;
            log_dr[n_log] = dr;
            log_at[n_log++] = CYCCNT;
        }
    }
}

static void report_registers(const char *prefix, uint32_t usart)
{
    static const char *const names[7] = { "sr", "dr", "brr", "cr1", "cr2", "cr3", "gtpr" };
    for (unsigned i = 0; i < 7; i++) {
        char name[24];
        unsigned n = 0;
        for (const char *p = prefix; *p; p++) {
            name[n++] = *p;
        }
        for (const char *p = names[i]; *p; p++) {
            name[n++] = *p;
        }
        name[n] = '\0';
        report(name, REG(usart + 4u * i));
    }
}

static void wait_until(uint32_t cycles)
{
    while (CYCCNT < cycles) {
    }
}

/* The cycles from a DR write until @flag: the byte goes out at once when the shift register is free */
static uint32_t send_until(uint32_t usart, uint8_t byte, uint32_t flag)
{
    (void)SR(usart);
    uint32_t t0 = CYCCNT;
    DR(usart) = byte;
    while (!(SR(usart) & flag)) {
    }
    return CYCCNT - t0;
}

static void registers(void)
{
    report_registers("reset_", USART1);
    SR(USART1) = 0; /* rc_w0: TC clears, TXE (read only) stays */
    report("w0_sr", SR(USART1));
    BRR(USART1) = CR2(USART1) = CR3(USART1) = GTPR(USART1) = 0xFFFFFFFFu;
    CR1(USART1) = 0xFFFFFFFFu & ~(CR1_TXEIE | CR1_TCIE); /* (no interrupt left pending) */
    report_registers("ones_", USART1);
    RCC_APB2RSTR = APB2_USART1;
    RCC_APB2RSTR = 0;
    report_registers("rst_", USART1);
    CR2(UART4) = CR3(UART4) = GTPR(UART4) = 0xFFFFFFFFu;
    report_registers("uart4_ones_", UART4);
}

static void frame_times(void)
{
    BRR(USART1) = BRR_100K;
    CR2(USART1) = CR2_STOP_2;
    SR(USART1) = ~SR_TC; /* (TC is set at reset: cleared to see the idle frame end) */
    uint32_t t0 = CYCCNT;
    CR1(USART1) = CR1_UE | CR1_M | CR1_PCE | CR1_TE; /* TE: an idle frame first */
    report("te_txe", SR(USART1));
    while (!(SR(USART1) & SR_TC)) {
    }
    report("idle_frame", CYCCNT - t0);
    (void)SR(USART1);
    t0 = CYCCNT;
    DR(USART1) = 0x55;
    report("write_sr", SR(USART1)); /* TC cleared by SR read then DR write; TXE back at once */
    DR(USART1) = 0xA5;
    report("write2_sr", SR(USART1)); /* the byte waits in DR */
    while (!(SR(USART1) & SR_TXE)) {
    }
    report("txe_at", CYCCNT - t0);
    while (!(SR(USART1) & SR_TC)) {
    }
    report("tc_at", CYCCNT - t0);

    CR2(USART1) = 0;
    CR1(USART1) = CR1_UE | CR1_TE | CR1_OVER8; /* 8N1 */
    BRR(USART1) = BRR_115200_OVER8;
    report("over8_frame", send_until(USART1, 0x3C, SR_TC));

    RCC_CFGR |= CFGR_PPRE1_DIV2;
    BRR(USART2) = BRR_100K_AT_8MHZ;
    SR(USART2) = ~SR_TC;
    CR1(USART2) = CR1_UE | CR1_TE;
    while (!(SR(USART2) & SR_TC)) {
    }
    report("apb1_frame", send_until(USART2, 0x42, SR_TC));
}

static void transmit_by_interrupt(void)
{
    BRR(USART1) = BRR_100K;
    CR2(USART1) = CR2_STOP_2;
    CR1(USART1) = SBUS_CR1;
    NVIC_ICPR1 = USART1_LINE;
    NVIC_ISER1 = USART1_LINE;
    uint32_t t0 = CYCCNT;
    CR1(USART1) = SBUS_CR1 | CR1_TXEIE;
    while (tc_irqs == 0) {
        __asm volatile("wfi");
    }
    report("txe_irqs", txe_irqs);
    report("tc_irqs", tc_irqs);
    report("tc_irq_at", tc_at - t0);
}

int main(void)
{
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1u;
    RCC_APB2ENR |= APB2_USART1;
    RCC_APB1ENR |= APB1_USART2 | APB1_UART4;
    registers();
    frame_times();
    transmit_by_interrupt();

    (void)SR(USART1);
    (void)DR(USART1);
    logging = 1;
    CR1(USART1) = SBUS_CR1 | CR1_RXNEIE | CR1_IDLEIE | CR1_PEIE;
    wait_until(20 * MS);
    CR1(USART1) = SBUS_CR1;
    logging = 0;
    wait_until(25 * MS);
    report("ore_sr", SR(USART1));
    report("ore_dr", DR(USART1));
    report("ore_sr_after", SR(USART1));

    report("n_log", n_log);
    for (uint32_t i = 0; i < n_log; i++) {
        report("log_sr", log_sr[i]);
        report("log_dr", log_dr[i]);
        report("log_at", log_at[i]);
    }
    return 0;
}
