/* The USARTs' DMA requests (RM0090 30.3.13 and the DMA's request mapping, tables 42/43), run standalone
   (the byte trace gives the instants on the line) and through the rig's link (the session sends SBUS on
   USART1; tests/stm32/test_usart_dma.py):
   - receive: USART1 set up for SBUS (100000 baud 8E2) with DMAR into a 32-byte circular buffer through
     DMA2 stream 5 channel 4, the IDLE interrupt marking each frame's end, as Betaflight's SBUS receiver
     does: at each IDLE the bytes from the last position to 32 - NDTR are copied out (up to 3 frames);
   - transmit by DMA: a 64-byte block on USART6 at 500000 baud 8N1 through DMA2 stream 6 channel 5 with
     HTIE and TCIE, and USART6's TC interrupt after the last byte; NDTR read after 10.5 frames;
   - transmit from the TXE interrupt: the same block, for the instants to be compared.
   Everything is reported through semihosting once the three frames came or 30 ms passed. The core runs
   on the 16 MHz HSI: HCLK = PCLK1 = PCLK2 = 16 MHz. */
#include "semihost.h"
#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))
#define RCC_AHB1ENR REG(0x40023830u)
#define RCC_APB2ENR REG(0x40023844u)
#define AHB1_DMA2 (1u << 22)
#define APB2_USART1 (1u << 4)
#define APB2_USART6 (1u << 5)
#define USART1 0x40011000u
#define USART6 0x40011400u
#define SR(u) REG((u) + 0x00u)
#define DR(u) REG((u) + 0x04u)
#define BRR(u) REG((u) + 0x08u)
#define CR1(u) REG((u) + 0x0Cu)
#define CR2(u) REG((u) + 0x10u)
#define CR3(u) REG((u) + 0x14u)
#define SR_IDLE (1u << 4)
#define SR_RXNE (1u << 5)
#define SR_TC (1u << 6)
#define SR_TXE (1u << 7)
#define CR1_RE (1u << 2)
#define CR1_TE (1u << 3)
#define CR1_IDLEIE (1u << 4)
#define CR1_TCIE (1u << 6)
#define CR1_TXEIE (1u << 7)
#define CR1_PCE (1u << 10)
#define CR1_M (1u << 12)
#define CR1_UE (1u << 13)
#define CR2_STOP_2 (2u << 12)
#define CR3_DMAR (1u << 6)
#define CR3_DMAT (1u << 7)
#define BRR_100K 160u /* 16 MHz / (16 x 10) */
#define BRR_500K 32u  /* 16 MHz / (16 x 2) */
/* DMA2 (RM0090 10.5) */
#define DMA2 0x40026400u
#define DMA_HISR REG(DMA2 + 0x04u)
#define DMA_HIFCR REG(DMA2 + 0x0Cu)
#define SCR(n) REG(DMA2 + 0x10u + 0x18u * (n))
#define SNDTR(n) REG(DMA2 + 0x14u + 0x18u * (n))
#define SPAR(n) REG(DMA2 + 0x18u + 0x18u * (n))
#define SM0AR(n) REG(DMA2 + 0x1Cu + 0x18u * (n))
#define CR_EN (1u << 0)
#define CR_HTIE (1u << 3)
#define CR_TCIE (1u << 4)
#define CR_M2P (1u << 6)
#define CR_CIRC (1u << 8)
#define CR_MINC (1u << 10)
#define CR_CHSEL(c) ((uint32_t)(c) << 25)
#define HISR_HTIF6 (1u << 20) /* stream 6: its flags from bit 16 */
#define HISR_TCIF6 (1u << 21)
#define DEMCR REG(0xE000EDFCu)
#define DWT_CTRL REG(0xE0001000u)
#define CYCCNT REG(0xE0001004u)
#define NVIC_ISER(n) REG(0xE000E100u + 4u * (n))
#define IRQ_USART1 37u
#define IRQ_DMA2_STREAM6 69u
#define IRQ_USART6 71u
#define MS 16000u       /* CYCCNT at 16 MHz */
#define FRAME_500K 320u /* 10 bits at 500000 baud: 20 us */

#define RX_SIZE 32u
#define FRAMES 3u
#define FRAME_LEN 25u
#define BLOCK 64u

static volatile uint8_t rx_buffer[RX_SIZE];
static volatile uint8_t frames[FRAMES][FRAME_LEN + 8];
static volatile uint32_t frame_len[FRAMES], frame_at[FRAMES], n_frames, rx_pos;
static uint8_t block[BLOCK];
static volatile uint32_t ht_at, tcif_at, tc_at, ht_irqs, tcif_irqs, eager_sent, eager_tc_at;

void usart1_handler(void)
{
    uint32_t sr = SR(USART1);
    if (sr & SR_IDLE) {
        (void)DR(USART1); /* IDLE's clear sequence: SR read, then DR read */
        uint32_t pos = RX_SIZE - SNDTR(5), n = 0;
        if (n_frames < FRAMES) {
            for (; rx_pos != pos && n < FRAME_LEN + 8; rx_pos = (rx_pos + 1) % RX_SIZE) {
                frames[n_frames][n++] = rx_buffer[rx_pos];
            }
            frame_len[n_frames] = n;
            frame_at[n_frames++] = CYCCNT;
        }
        rx_pos = pos;
    }
}

void dma2_stream6_handler(void)
{
    uint32_t hisr = DMA_HISR;
    if (hisr & HISR_HTIF6) {
        ht_at = CYCCNT;
        ht_irqs++;
    }
    if (hisr & HISR_TCIF6) {
        tcif_at = CYCCNT;
        tcif_irqs++;
    }
    DMA_HIFCR = hisr & (HISR_HTIF6 | HISR_TCIF6);
}

void usart6_handler(void)
{
    uint32_t sr = SR(USART6), cr1 = CR1(USART6);
    if ((cr1 & CR1_TXEIE) && (sr & SR_TXE)) {
        if (eager_sent < BLOCK) {
            DR(USART6) = block[eager_sent++];
        } else {
            CR1(USART6) = (cr1 & ~CR1_TXEIE) | CR1_TCIE;
        }
    } else if ((cr1 & CR1_TCIE) && (sr & SR_TC)) {
        CR1(USART6) = cr1 & ~CR1_TCIE;
        if (eager_sent) {
            eager_tc_at = CYCCNT;
        } else {
            tc_at = CYCCNT;
        }
    }
}

static void receive_by_dma(void)
{
    SPAR(5) = USART1 + 0x04u;
    SM0AR(5) = (uint32_t)rx_buffer;
    SNDTR(5) = RX_SIZE;
    SCR(5) = CR_CHSEL(4) | CR_MINC | CR_CIRC; /* peripheral-to-memory, bytes */
    SCR(5) |= CR_EN;
    BRR(USART1) = BRR_100K;
    CR2(USART1) = CR2_STOP_2;
    CR3(USART1) = CR3_DMAR;
    NVIC_ISER(IRQ_USART1 / 32u) = 1u << (IRQ_USART1 % 32u);
    CR1(USART1) = CR1_UE | CR1_M | CR1_PCE | CR1_RE | CR1_IDLEIE;
}

static void transmit_by_dma(void)
{
    BRR(USART6) = BRR_500K;
    SR(USART6) = ~SR_TC;           /* rc_w0 (TC is set at reset: cleared to see the idle frame's end) */
    CR1(USART6) = CR1_UE | CR1_TE; /* TE: an idle frame first */
    while (!(SR(USART6) & SR_TC)) {
    }
    SR(USART6) = ~SR_TC;
    CR3(USART6) = CR3_DMAT;
    SPAR(6) = USART6 + 0x04u;
    SM0AR(6) = (uint32_t)block;
    SNDTR(6) = BLOCK;
    SCR(6) = CR_CHSEL(5) | CR_M2P | CR_MINC | CR_HTIE | CR_TCIE;
    NVIC_ISER(IRQ_DMA2_STREAM6 / 32u) = 1u << (IRQ_DMA2_STREAM6 % 32u);
    NVIC_ISER(IRQ_USART6 / 32u) = 1u << (IRQ_USART6 % 32u);
    CR1(USART6) = CR1_UE | CR1_TE | CR1_TCIE;
    uint32_t t0 = CYCCNT;
    SCR(6) |= CR_EN;
    while (CYCCNT - t0 < 10u * FRAME_500K + FRAME_500K / 2u) {
    }
    report("ndtr_mid", SNDTR(6));
    while (tc_at == 0) {
        __asm volatile("wfi");
    }
    report("tx_ht_at", ht_at - t0);
    report("tx_tcif_at", tcif_at - t0);
    report("tx_tc_at", tc_at - t0);
    report("tx_ht_irqs", ht_irqs);
    report("tx_tcif_irqs", tcif_irqs);
    report("tx_scr_after", SCR(6));
    report("tx_ndtr_after", SNDTR(6));
}

static void transmit_by_interrupt(void)
{
    CR3(USART6) = 0;
    (void)SR(USART6);
    uint32_t t0 = CYCCNT;
    DR(USART6) = block[eager_sent++]; /* (after an SR read: TC's clear sequence) */
    CR1(USART6) = CR1_UE | CR1_TE | CR1_TXEIE;
    while (eager_tc_at == 0) {
        __asm volatile("wfi");
    }
    report("eager_tc_at", eager_tc_at - t0);
}

int main(void)
{
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1u;
    for (unsigned i = 0; i < BLOCK; i++) {
        block[i] = (uint8_t)(i * 37u + 11u);
    }
    RCC_AHB1ENR |= AHB1_DMA2;
    RCC_APB2ENR |= APB2_USART1 | APB2_USART6;
    receive_by_dma();
    transmit_by_dma();
    transmit_by_interrupt();
    while (n_frames < FRAMES && CYCCNT < 30u * MS) {
    }
    report("n_frames", n_frames);
    for (unsigned f = 0; f < n_frames; f++) {
        char name[16] = { 'f', (char)('0' + f), '_', 'l', 'e', 'n', '\0' };
        report(name, frame_len[f]);
        name[3] = 'a', name[4] = 't', name[5] = '\0';
        report(name, frame_at[f]);
        for (unsigned i = 0; i < frame_len[f]; i++) {
            char byte_name[16] = { 'f', (char)('0' + f), '_', 'b', (char)('0' + i / 10u), (char)('0' + i % 10u), '\0' };
            report(byte_name, frames[f][i]);
        }
    }
    report("rx_sr", SR(USART1));
    put_text("done\n");
    return 0;
}
