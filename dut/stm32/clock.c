/* The clock (clock.h): ST's SystemClock_Config sequence with the board's PLL, bus prescalers, flash wait
   states and regulator scale (board.h: 168 MHz from an 8 MHz HSE on the F405 board, 100 MHz from 25 MHz
   on the Black Pill), then DWT_CYCCNT and SysTick from HCLK. */
#include "clock.h"

#include "board.h"
#include "stm32f405.h"

static volatile uint32_t ms;
static uint32_t wraps, last; /* clock_seconds: the cycle counter's wraps */

void systick_handler(void);
void systick_handler(void) { ms++; }

void clock_init(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_PWREN;
    PWR_CR |= BOARD_PWR_VOS;
    RCC_CR |= RCC_CR_HSEON;
    while (!(RCC_CR & RCC_CR_HSERDY))
        ;
    RCC_CFGR |= BOARD_CFGR_PPRE;
    RCC_PLLCFGR = BOARD_PLLCFGR;
    RCC_CR |= RCC_CR_PLLON;
    while (!(RCC_CR & RCC_CR_PLLRDY))
        ;
    FLASH_ACR = FLASH_ACR_ICEN | FLASH_ACR_DCEN | FLASH_ACR_PRFTEN | BOARD_FLASH_LATENCY;
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC_CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL)
        ;
    DEMCR |= DEMCR_TRCENA;
    DWT_CYCCNT = 0;
    DWT_CTRL |= 1u;
    SYST_RVR = BOARD_HCLK_HZ / SYSTICK_HZ - 1u;
    SYST_CVR = 0;
    SYST_CSR = 7u; /* the processor clock, its interrupt, on */
}

uint32_t clock_ticks(void) { return DWT_CYCCNT; }

double clock_seconds(void)
{
    uint32_t t = DWT_CYCCNT;
    if (t < last)
        wraps++;
    last = t;
    return ((double)wraps * 4294967296.0 + (double)t) / (double)BOARD_HCLK_HZ;
}

/* From a millisecond up: asleep until SysTick has ticked that many times (a polled cycle counter costs
   QEMU an MMIO exit a poll). The first tick may come at once, but calls back to back (src/sensors.c
   waits 100 ms as 100 waits of 1 ms) start on a tick, so all but the first wait whole milliseconds.
   Below a millisecond, by the cycle counter. */
void clock_wait_us(uint16_t us)
{
    if (us >= 1000) {
        clock_sleep_until_ms(ms + (us + 999u) / 1000u);
        return;
    }
    uint32_t t0 = DWT_CYCCNT;
    while (DWT_CYCCNT - t0 < (BOARD_HCLK_HZ / 1000000UL) * us)
        ;
}

uint32_t clock_ms(void) { return ms; }

void clock_sleep_until_ms(uint32_t until)
{
    while ((int32_t)(ms - until) < 0)
        __asm volatile("wfi");
}
