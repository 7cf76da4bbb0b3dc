/* A battery monitor while a motor runs (tests/stm32/test_battery.py runs it on the STM32F405 board with the
   board's own [battery] on PC2, ADC123_IN12): at the reset clock (16 MHz HSI, APB1 undivided), motor 1's
   output S1 (PB0, TIM3_CH3, AF2) pulses 1000 us (zero throttle) every 2.041 ms for the first 8 readings,
   then 2000 us (full throttle); ADC1 converts channel 12 (480 cycles) every 10 ms or so, and each reading
   goes out on USART6 TX (the board's telemetry port) as a line, "ADC 1421". */
#include "text_out.h"
#include "timer_checks.h"

#define ADC1_SR REG(0x40012000u)
#define ADC1_CR2 REG(0x40012008u)
#define ADC1_SMPR1 REG(0x4001200Cu)
#define ADC1_SQR3 REG(0x40012034u)
#define ADC1_DR REG(0x4001204Cu)
#define ADC_SR_EOC (1u << 1)
#define ADC_CR2_ADON (1u << 0)
#define ADC_CR2_SWSTART (1u << 30)
#define RCC_APB2ENR_ADC1EN (1u << 8)
#define BATTERY_CHANNEL 12u
#define READING_CYCLES 160000u /* 10 ms at 16 MHz */

int main(void)
{
    RCC_APB2ENR |= RCC_APB2ENR_USART6EN | RCC_APB2ENR_ADC1EN;
    USART_CR1(USART6_BASE) = USART_CR1_UE | USART_CR1_TE;
    RCC_APB1ENR |= 1u << 1; /* TIM3 */
    pin_af(PORT_B, 0, 2);
    TIM_CCR(TIM3_BASE, 3) = 1000u;
    TIM_CCMR2(TIM3_BASE) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(TIM3_BASE) = TIM_CCER_E(3);
    timer_start(TIM3_BASE, 15u, 2040u, TIM_CR1_ARPE); /* 1 us ticks */
    RCC_AHB1ENR |= 1u << PORT_C;
    GPIO_MODER(PORT_C) |= 3u << (2 * 2); /* PC2 analog */
    ADC1_SMPR1 = 7u << (3 * (BATTERY_CHANNEL - 10u));
    ADC1_SQR3 = BATTERY_CHANNEL;
    ADC1_CR2 = ADC_CR2_ADON;
    DEMCR |= DEMCR_TRCENA;
    DWT_CTRL |= 1u;
    for (unsigned n = 0;; n++) {
        if (n == 8u) {
            TIM_CCR(TIM3_BASE, 3) = 2000u;
        }
        uint32_t start = DWT_CYCCNT;
        ADC1_CR2 = ADC_CR2_ADON | ADC_CR2_SWSTART;
        while (!(ADC1_SR & ADC_SR_EOC)) {
        }
        char line[16] = "ADC";
        char *end = decimal(line + 3, ADC1_DR);
        *end++ = '\n';
        *end = '\0';
        usart6_text(line);
        while (DWT_CYCCNT - start < READING_CYCLES) {
        }
    }
}
