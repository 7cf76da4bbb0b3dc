/* One loop timed with DWT_CYCCNT and SysTick, for the test firmwares that compare the core's clock before
 * and after a clock set-up (clock_gpio.c, f411_map.c): the same instructions every call, so under icount
 * the same virtual time, and the counts scale with HCLK and nothing else. */
#ifndef SPIN_TIMING_H
#define SPIN_TIMING_H

#include "semihost.h"
#include "stm32f405.h"

#define SPIN_ROUNDS 10000u

__attribute__((noinline, unused)) static void spin(uint32_t rounds)
{
    for (volatile uint32_t i = 0; i < rounds; i++) {
    }
}

/* The loop's HCLK cycles (@dwt_name) and SysTick ticks (@systick_name), reported */
static inline void time_spin(const char *dwt_name, const char *systick_name)
{
    SYST_RVR = 0x00FFFFFFu;
    SYST_CVR = 0;
    SYST_CSR = 0x5u;        /* ENABLE, CLKSOURCE = the processor clock */
    while (SYST_CVR == 0) { /* the first tick loads RVR */
    }
    uint32_t tick0 = SYST_CVR;
    uint32_t cyc0 = DWT_CYCCNT;
    spin(SPIN_ROUNDS);
    uint32_t cyc1 = DWT_CYCCNT;
    uint32_t tick1 = SYST_CVR;
    SYST_CSR = 0;
    report(dwt_name, cyc1 - cyc0);
    report(systick_name, (tick0 - tick1) & 0x00FFFFFFu); /* SysTick counts down */
}

#endif
