/* USART1's SBUS (sbus_rx.h) received as Betaflight does: the DMA (the board's SBUS_DMA stream, circular)
   takes each byte from DR into a ring, and the IDLE interrupt (a frame's time of idle line after a byte,
   RM0090 30.6.1) marks a frame's end: the bytes from the last position to the ring's size less NDTR are
   the frame, copied for the loop, which decodes it with the portable sbus_decode. No interrupt a byte. */
#include "sbus_rx.h"

#include <string.h>

#include "board.h"
#include "stm32f405.h"

#define RING 64u /* two frames and more: a frame is never overwritten before its IDLE */
#define STREAM SBUS_DMA_STREAM

static volatile uint8_t ring[RING];
static uint32_t last; /* where the next frame starts in the ring */
static volatile uint8_t ready_bad, ready;
static uint8_t ready_buf[SBUS_FRAME];
static volatile sbus_rx_stats stats;

void usart1_handler(void);
void usart1_handler(void)
{
    uint32_t status = USART_SR(USART1_BASE);
    (void)USART_DR(USART1_BASE); /* SR then DR: IDLE and the error flags clear (the DMA took the bytes) */
    if (!(status & USART_SR_IDLE))
        return;
    uint32_t end = RING - DMA_SNDTR(SBUS_DMA, STREAM), n = (end + RING - last) % RING;
    uint8_t bad = 0;
    if (status & (USART_SR_PE | USART_SR_FE | USART_SR_ORE)) {
        stats.byte_errors++;
        bad = 1;
    }
    if (n == SBUS_FRAME) {
        if (ready)
            stats.dropped++;
        for (uint32_t i = 0; i < SBUS_FRAME; i++)
            ready_buf[i] = ring[(last + i) % RING];
        ready_bad = bad;
        ready = 1;
    } else if (n != 0) {
        stats.bad_frames++; /* a frame cut short or run together: not one to decode */
    }
    last = end;
}

void sbus_rx_init(void)
{
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    RCC_AHB1ENR |= (1u << PORT_A) | SBUS_DMA_EN;
    GPIO_MODER(PORT_A) = (GPIO_MODER(PORT_A) & ~(3u << 20)) | (GPIO_MODE_AF << 20);
    GPIO_AFRH(PORT_A) = (GPIO_AFRH(PORT_A) & ~(0xFu << 8)) | (7u << 8); /* PA10 AF7: USART1_RX */
    DMA_SPAR(SBUS_DMA, STREAM) = (uint32_t)&USART_DR(USART1_BASE);
    DMA_SM0AR(SBUS_DMA, STREAM) = (uint32_t)ring;
    DMA_SNDTR(SBUS_DMA, STREAM) = RING;
    DMA_SCR(SBUS_DMA, STREAM) = DMA_SCR_CHSEL(SBUS_DMA_CHANNEL) | DMA_SCR_MINC | DMA_SCR_CIRC; /* to memory, bytes */
    DMA_SCR(SBUS_DMA, STREAM) |= DMA_SCR_EN;
    USART_BRR(USART1_BASE) = (uint32_t)((BOARD_APB2_HZ * 2 / SBUS_BAUD + 1) / 2); /* 16x oversampling */
    USART_CR2(USART1_BASE) = USART_CR2_STOP_2;
    USART_CR3(USART1_BASE) = USART_CR3_DMAR;
    /* 9-bit words with the parity bit: 8 data bits, even parity */
    USART_CR1(USART1_BASE) = USART_CR1_UE | USART_CR1_M | USART_CR1_PCE | USART_CR1_RE | USART_CR1_IDLEIE;
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
