/* USART1 (PA10 RX, PA9 TX: an Omnibus F4's SBUS port) set up for SBUS's frame, 100000 baud 8E2 (9-bit
   words with the parity bit, two stop bits; RM0090 30.6), echoing every byte it receives: the STM32
   tier's link must put the session's bytes into the receiver at their frame times and bring the
   firmware's bytes back. It never ends. */
#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))
#define RCC_APB2ENR REG(0x40023844u)
#define RCC_APB2ENR_USART1EN (1u << 4)
#define USART1_SR REG(0x40011000u)
#define USART1_DR REG(0x40011004u)
#define USART1_BRR REG(0x40011008u)
#define USART1_CR1 REG(0x4001100Cu)
#define USART1_CR2 REG(0x40011010u)
#define SR_RXNE (1u << 5)
#define SR_TXE (1u << 7)
#define CR1_UE (1u << 13)
#define CR1_M (1u << 12)
#define CR1_PCE (1u << 10)
#define CR1_TE (1u << 3)
#define CR1_RE (1u << 2)
#define CR2_STOP_2 (2u << 12)
#define BRR_100K_AT_16MHZ 160u /* 16 MHz / (16 * 10): 100000 baud from the HSI */

int main(void)
{
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    USART1_BRR = BRR_100K_AT_16MHZ;
    USART1_CR2 = CR2_STOP_2;
    USART1_CR1 = CR1_UE | CR1_M | CR1_PCE | CR1_TE | CR1_RE;
    for (;;) {
        while (!(USART1_SR & SR_RXNE)) {
        }
        uint32_t byte = USART1_DR & 0xFFu;
        while (!(USART1_SR & SR_TXE)) {
        }
        USART1_DR = byte;
    }
}
