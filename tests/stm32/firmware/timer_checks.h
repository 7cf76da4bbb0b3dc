/* What the timer test firmwares share: ST's 168 MHz clock set-up (HSE 8 MHz, PLL M=8 N=336 P=2, APB1 /4
   and APB2 /2, so the timers' clocks are 84 MHz on APB1 and 168 MHz on APB2), pins put on an alternate
   function, and a pin's pulse measured by polling its IDR against DWT_CYCCNT. */
#ifndef TIMER_CHECKS_H
#define TIMER_CHECKS_H

#include "semihost.h"
#include "stm32f405.h"

#define CORE_HZ 168000000u
#define NO_EDGE 0xFFFFFFFFu

static inline void clock_168mhz(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_PWREN;
    PWR_CR |= PWR_CR_VOS;
    RCC_CR |= RCC_CR_HSEON;
    while (!(RCC_CR & RCC_CR_HSERDY)) {
    }
    RCC_CFGR |= RCC_CFGR_PPRE2_DIV2 | RCC_CFGR_PPRE1_DIV4;
    RCC_PLLCFGR = 8u | (336u << 6) | RCC_PLLCFGR_PLLSRC_HSE | (7u << 24);
    RCC_CR |= RCC_CR_PLLON;
    while (!(RCC_CR & RCC_CR_PLLRDY)) {
    }
    FLASH_ACR = FLASH_ACR_ICEN | FLASH_ACR_DCEN | FLASH_ACR_PRFTEN | FLASH_ACR_LATENCY_5WS;
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC_CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL) {
    }
    DEMCR |= DEMCR_TRCENA;
    DWT_CYCCNT = 0;
    DWT_CTRL |= 1u;
}

/* @pin of @port on alternate function @af (its port's clock on) */
static inline void pin_af(uint32_t port, unsigned pin, unsigned af)
{
    RCC_AHB1ENR |= 1u << port;
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2 * pin))) | (GPIO_MODE_AF << (2 * pin));
    if (pin < 8) {
        GPIO_AFRL(port) = (GPIO_AFRL(port) & ~(0xFu << (4 * pin))) | (af << (4 * pin));
    } else {
        GPIO_AFRH(port) = (GPIO_AFRH(port) & ~(0xFu << (4 * (pin - 8)))) | (af << (4 * (pin - 8)));
    }
}

/* Starts the timer at @base: PSC and ARR (with @cr1's other bits, ARPE among them), taken with the CCRx and
   CCMRx written before by UG into the shadow registers, UIF cleared, then CEN */
static inline void timer_start(uint32_t base, uint32_t psc, uint32_t arr, uint32_t cr1)
{
    TIM_PSC(base) = psc;
    TIM_ARR(base) = arr;
    TIM_CR1(base) = cr1;
    TIM_EGR(base) = TIM_EGR_UG;
    TIM_SR(base) = 0;
    TIM_CR1(base) = cr1 | TIM_CR1_CEN;
}

static inline unsigned pin_level(uint32_t port, unsigned pin) { return GPIO_IDR(port) >> pin & 1u; }

/* Waits (at most @limit cycles) for the pin to read @level: 1 and the cycle count then in @at, or 0 */
static inline int wait_for_level(uint32_t port, unsigned pin, unsigned level, uint32_t limit, uint32_t *at)
{
    uint32_t start = DWT_CYCCNT;
    while (pin_level(port, pin) != level) {
        if (DWT_CYCCNT - start > limit) {
            return 0;
        }
    }
    *at = DWT_CYCCNT;
    return 1;
}

/* One period of the pin's pulse train, from a rising edge: its high time and period in core cycles
   (NO_EDGE when the pin did not move within @limit cycles) */
static inline void measure_pulse(uint32_t port, unsigned pin, uint32_t limit, uint32_t *high, uint32_t *period)
{
    uint32_t skip, rise, fall, next;
    if (wait_for_level(port, pin, 0, limit, &skip) && wait_for_level(port, pin, 1, limit, &rise) &&
        wait_for_level(port, pin, 0, limit, &fall) && wait_for_level(port, pin, 1, limit, &next)) {
        *high = fall - rise;
        *period = next - rise;
    } else {
        *high = *period = NO_EDGE;
    }
}

#endif
