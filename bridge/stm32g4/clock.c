/* The clock tree and the watchdog (see clock.h). */
#include "clock.h"

#include "regs.h"

void clock_init_170mhz(void)
{
    /* range 1 boost (RM0440 §6.1.5): the regulator first, then the wait states, then the clock */
    RCC_APB1ENR1 |= RCC_APB1ENR1_PWREN;
    (void)RCC_APB1ENR1;
    PWR_CR1 = (PWR_CR1 & ~PWR_CR1_VOS_MASK) | PWR_CR1_VOS_RANGE1;
    while (PWR_SR2 & PWR_SR2_VOSF) {
    }
    PWR_CR5 &= ~PWR_CR5_R1MODE;
    /* 4 wait states at 170 MHz (§5.3.3 Table 29), prefetch and caches on */
    FLASH_ACR = (FLASH_ACR & ~FLASH_ACR_LATENCY_MASK) | 4u | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN;
    while ((FLASH_ACR & FLASH_ACR_LATENCY_MASK) != 4u) {
    }
    RCC_CR |= RCC_CR_HSION;
    while (!(RCC_CR & RCC_CR_HSIRDY)) {
    }
    /* HSI16 / 4 = 4 MHz into the PLL (2.66..8 MHz), x 85 = 340 MHz VCO (96..344 MHz), / 2 = 170 MHz */
    RCC_CR &= ~RCC_CR_PLLON;
    while (RCC_CR & RCC_CR_PLLRDY) {
    }
    RCC_PLLCFGR = RCC_PLLCFGR_SRC_HSI16 | RCC_PLLCFGR_M(4u) | RCC_PLLCFGR_N(85u) | RCC_PLLCFGR_R_DIV2 | RCC_PLLCFGR_REN;
    RCC_CR |= RCC_CR_PLLON;
    while (!(RCC_CR & RCC_CR_PLLRDY)) {
    }
    /* above 80 MHz the switch goes through AHB / 2 for at least 1 us (§7.2.7), then AHB / 1; APB1 and
       APB2 stay / 1 (PCLK1 = PCLK2 = 170 MHz) */
    RCC_CFGR = (RCC_CFGR & ~(RCC_CFGR_HPRE_MASK | RCC_CFGR_SW_MASK)) | RCC_CFGR_HPRE_DIV2 | RCC_CFGR_SW_PLL;
    while ((RCC_CFGR & RCC_CFGR_SWS_MASK) != RCC_CFGR_SWS_PLL) {
    }
    for (volatile unsigned i = 0; i < 200; i++) { /* >= 1 us at 85 MHz */
    }
    RCC_CFGR &= ~RCC_CFGR_HPRE_MASK;
}

int watchdog_start(void)
{
    int was_reset = (RCC_CSR & RCC_CSR_IWDGRSTF) != 0;
    RCC_CSR |= RCC_CSR_RMVF;
    IWDG_KR = IWDG_KEY_START; /* starts the LSI too */
    IWDG_KR = IWDG_KEY_UNLOCK;
    IWDG_PR = 3u;    /* LSI / 32: 1 ms at 32 kHz */
    IWDG_RLR = 100u; /* 100 ms */
    while (IWDG_SR & 7u) {
    }
    IWDG_KR = IWDG_KEY_RELOAD;
    return was_reset;
}

void watchdog_feed(void) { IWDG_KR = IWDG_KEY_RELOAD; }
