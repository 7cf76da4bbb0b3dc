/* USART1's receive interrupt (sbus_rx.h): bytes assembled into a frame buffer; a finished frame is copied
   for the loop, which decodes it with the portable sbus_decode. The gap is timed on the cycle counter. */
#include "sbus_rx.h"

#include <string.h>

#include "board.h"
#include "clock.h"
#include "stm32f405.h"

static uint8_t buf[SBUS_FRAME], n, spoilt;
static uint32_t last_byte;
static volatile uint8_t ready_bad, ready;
static uint8_t ready_buf[SBUS_FRAME];
static volatile sbus_rx_stats stats;

void usart1_handler(void);
void usart1_handler(void)
{
    uint32_t status = USART_SR(USART1_BASE), b = USART_DR(USART1_BASE); /* SR then DR: the flags clear */
    if (!(status & USART_SR_RXNE))
        return;
    uint32_t now = clock_ticks();
    if (now - last_byte > 2UL * SBUS_GAP_US * (TICKS_PER_S / 2000000UL)) {
        n = 0; /* silence: the next byte starts a frame */
        spoilt = 0;
    }
    last_byte = now;
    if (status & (USART_SR_PE | USART_SR_FE | USART_SR_ORE)) {
        stats.byte_errors++;
        spoilt = 1;
    }
    if (n >= SBUS_FRAME)
        return; /* more than a frame without a gap: wait for one */
    buf[n++] = (uint8_t)b;
    if (n == SBUS_FRAME) {
        if (ready)
            stats.dropped++;
        memcpy(ready_buf, buf, SBUS_FRAME);
        ready_bad = spoilt;
        ready = 1;
    }
}

void sbus_rx_init(void)
{
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    RCC_AHB1ENR |= 1u << PORT_A;
    GPIO_MODER(PORT_A) = (GPIO_MODER(PORT_A) & ~(3u << 20)) | (GPIO_MODE_AF << 20);
    GPIO_AFRH(PORT_A) = (GPIO_AFRH(PORT_A) & ~(0xFu << 8)) | (7u << 8);           /* PA10 AF7: USART1_RX */
    USART_BRR(USART1_BASE) = (uint32_t)((BOARD_APB2_HZ * 2 / SBUS_BAUD + 1) / 2); /* 16x oversampling */
    USART_CR2(USART1_BASE) = USART_CR2_STOP_2;
    /* 9-bit words with the parity bit: 8 data bits, even parity */
    USART_CR1(USART1_BASE) = USART_CR1_UE | USART_CR1_M | USART_CR1_PCE | USART_CR1_RE | USART_CR1_RXNEIE;
    NVIC_ISER(USART1_IRQ / 32u) = 1u << (USART1_IRQ % 32u);
}

int sbus_rx_take(sbus_frame *out)
{
    uint8_t f[SBUS_FRAME], bad;
    __asm volatile("cpsid i" ::: "memory");
    if (!ready) {
        __asm volatile("cpsie i" ::: "memory");
        return 0;
    }
    memcpy(f, ready_buf, SBUS_FRAME);
    bad = ready_bad;
    ready = 0;
    __asm volatile("cpsie i" ::: "memory");
    if (bad || sbus_decode(f, out) < 0) {
        stats.bad_frames++; /* (the interrupt writes the other counters only) */
        return -1;
    }
    stats.frames++;
    return 1;
}

sbus_rx_stats sbus_rx_counters(void)
{
    sbus_rx_stats s;
    __asm volatile("cpsid i" ::: "memory");
    s = (sbus_rx_stats){ stats.frames, stats.bad_frames, stats.byte_errors, stats.dropped };
    __asm volatile("cpsie i" ::: "memory");
    return s;
}
