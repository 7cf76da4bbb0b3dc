/* USART1's receiver fed two ways with the same SBUS frames (100000 baud 8E2, sent through the rig's link;
   tests/stm32/test_usart_rx_paths.py): first by the RXNE interrupt (the core takes each byte from DR),
   then by DMA2 stream 5 channel 4 into a 32-byte circular buffer (RM0090 table 43) with the RXNE
   interrupt off, as Betaflight's SBUS receiver does. Both with the IDLE interrupt: at each IDLE the
   firmware notes CYCCNT and the error flags the frame left (the RXNE path: those seen with each byte;
   the DMA path: SR at IDLE), and the DMA path copies the bytes from its last position to 32 - NDTR.
   Each phase gets three frames, the third with odd parity (PE on each byte, 30.6.1). The DMA path has
   the stream's HTIE and TCIE on too: their first instants are noted in its interrupt. The core runs on
   the 16 MHz HSI; everything is reported once the six frames came or 60 ms passed. */
#include "semihost.h"
#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))
#define RCC_AHB1ENR REG(0x40023830u)
#define RCC_APB2ENR REG(0x40023844u)
#define AHB1_DMA2 (1u << 22)
#define APB2_USART1 (1u << 4)
#define USART1 0x40011000u
#define SR REG(USART1 + 0x00u)
#define DR REG(USART1 + 0x04u)
#define BRR REG(USART1 + 0x08u)
#define CR1 REG(USART1 + 0x0Cu)
#define CR2 REG(USART1 + 0x10u)
#define CR3 REG(USART1 + 0x14u)
#define SR_ERRORS 0xFu /* PE, FE, NF, ORE */
#define SR_IDLE (1u << 4)
#define SR_RXNE (1u << 5)
#define CR1_RE (1u << 2)
#define CR1_IDLEIE (1u << 4)
#define CR1_RXNEIE (1u << 5)
#define CR1_PCE (1u << 10)
#define CR1_M (1u << 12)
#define CR1_UE (1u << 13)
#define CR2_STOP_2 (2u << 12)
#define CR3_DMAR (1u << 6)
#define BRR_100K 160u /* 16 MHz / (16 x 10) */
#define DMA2 0x40026400u
#define DMA_HISR REG(DMA2 + 0x04u)
#define DMA_HIFCR REG(DMA2 + 0x0Cu)
#define HISR_HTIF5 (1u << 10) /* stream 5: its flags from bit 6 */
#define HISR_TCIF5 (1u << 11)
#define SCR REG(DMA2 + 0x10u + 0x18u * 5u)
#define SNDTR REG(DMA2 + 0x14u + 0x18u * 5u)
#define SPAR REG(DMA2 + 0x18u + 0x18u * 5u)
#define SM0AR REG(DMA2 + 0x1Cu + 0x18u * 5u)
#define CR_EN (1u << 0)
#define CR_HTIE (1u << 3)
#define CR_TCIE (1u << 4)
#define CR_CIRC (1u << 8)
#define CR_MINC (1u << 10)
#define CR_CHSEL(c) ((uint32_t)(c) << 25)
#define DEMCR REG(0xE000EDFCu)
#define DWT_CTRL REG(0xE0001000u)
#define CYCCNT REG(0xE0001004u)
#define NVIC_ISER(n) REG(0xE000E100u + 4u * (n))
#define IRQ_USART1 37u
#define IRQ_DMA2_STREAM5 68u
#define MS 16000u /* CYCCNT at 16 MHz */

#define RX_SIZE 32u
#define FRAMES 3u
#define FRAME_LEN 25u

static volatile uint8_t rx_buffer[RX_SIZE];
static volatile uint8_t got[2][FRAMES * FRAME_LEN];
static volatile uint32_t ht_at, tc_at, dma_start;
static volatile uint32_t n_got[2], idle_at[2][FRAMES], idle_flags[2][FRAMES], n_idle[2], rx_pos, errors, by_dma;

void usart1_handler(void)
{
    uint32_t now = CYCCNT, sr = SR, p = by_dma; /* (CYCCNT first: the paths' ISRs differ after) */
    if (sr & SR_RXNE) {                         /* (the RXNE path only: with the DMA, RXNE never stays set) */
        uint8_t b = (uint8_t)DR;
        errors |= sr & SR_ERRORS;
        if (n_got[p] < FRAMES * FRAME_LEN) {
            got[p][n_got[p]++] = b;
        }
    }
    if (sr & SR_IDLE) {
        (void)DR; /* IDLE's clear sequence: SR read, then DR read */
        if (p) {
            uint32_t pos = RX_SIZE - SNDTR;
            for (; rx_pos != pos; rx_pos = (rx_pos + 1) % RX_SIZE) {
                if (n_got[p] < FRAMES * FRAME_LEN) {
                    got[p][n_got[p]++] = rx_buffer[rx_pos];
                }
            }
            errors = sr & SR_ERRORS;
        }
        if (n_idle[p] < FRAMES) {
            idle_at[p][n_idle[p]] = now;
            idle_flags[p][n_idle[p]++] = errors;
        }
        errors = 0;
    }
}

void dma2_stream5_handler(void)
{
    uint32_t now = CYCCNT, hisr = DMA_HISR;
    if ((hisr & HISR_HTIF5) && ht_at == 0) {
        ht_at = now;
    }
    if ((hisr & HISR_TCIF5) && tc_at == 0) {
        tc_at = now;
    }
    DMA_HIFCR = hisr & (HISR_HTIF5 | HISR_TCIF5);
}

static void report_phase(unsigned p)
{
    char name[16] = { 'p', (char)('0' + p), '_', 'n', '\0' };
    report(name, n_got[p]);
    for (unsigned k = 0; k < FRAMES; k++) {
        char at[16] = { 'p', (char)('0' + p), '_', 'i', 'd', 'l', 'e', (char)('0' + k), '\0' };
        report(at, idle_at[p][k]);
        at[3] = 'e', at[4] = 'r', at[5] = 'r', at[6] = (char)('0' + k), at[7] = '\0';
        report(at, idle_flags[p][k]);
    }
    for (unsigned i = 0; i < n_got[p]; i++) {
        char b[16] = { 'p', (char)('0' + p), '_', 'b', (char)('0' + i / 10u), (char)('0' + i % 10u), '\0' };
        report(b, got[p][i]);
    }
}

int main(void)
{
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1u;
    RCC_AHB1ENR |= AHB1_DMA2;
    RCC_APB2ENR |= APB2_USART1;
    BRR = BRR_100K;
    CR2 = CR2_STOP_2;
    NVIC_ISER(IRQ_USART1 / 32u) = 1u << (IRQ_USART1 % 32u);
    CR1 = CR1_UE | CR1_M | CR1_PCE | CR1_RE | CR1_RXNEIE | CR1_IDLEIE;
    while (n_idle[0] < FRAMES && CYCCNT < 30u * MS) {
        __asm volatile("wfi");
    }
    CR1 = 0;
    by_dma = 1;
    SPAR = USART1 + 0x04u;
    SM0AR = (uint32_t)rx_buffer;
    SNDTR = RX_SIZE;
    SCR = CR_CHSEL(4) | CR_MINC | CR_CIRC | CR_HTIE | CR_TCIE; /* peripheral-to-memory, bytes */
    NVIC_ISER(IRQ_DMA2_STREAM5 / 32u) = 1u << (IRQ_DMA2_STREAM5 % 32u);
    SCR |= CR_EN;
    CR3 = CR3_DMAR;
    CR1 = CR1_UE | CR1_M | CR1_PCE | CR1_RE | CR1_IDLEIE;
    while (n_idle[1] < FRAMES && CYCCNT < 60u * MS) {
        __asm volatile("wfi");
    }
    report_phase(0);
    report_phase(1);
    report("ht_at", ht_at);
    report("tc_at", tc_at);
    put_text("done\n");
    return 0;
}
