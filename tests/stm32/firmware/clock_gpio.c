/* The clock and GPIO test firmware of the STM32 tier: reports the RCC, PWR, FLASH and GPIO registers at
   reset, runs CMSIS SystemInit, sets up 168 MHz from an 8 MHz HSE through the PLL the way ST's CMSIS SystemInit and HAL
   SystemClock_Config do (PWR scale 1, HSE on and ready, PLL M=8 N=336 P=2 Q=7, five flash wait states,
   AHB /1, APB1 /4, APB2 /2, switch to the PLL and wait for SWS), times the same loop with DWT_CYCCNT and
   SysTick before and after, and drives GPIOD (PD12 as a Discovery board's LED). Every value goes out as
   a NAME=0xVALUE line through semihosting; tests/stm32/test_clock_gpio.py judges them against RM0090. */
#include "semihost.h"
#include "spin_timing.h"
#include "stm32f405.h"

static void clock_at_reset(void)
{
    report("rcc_cr_reset", RCC_CR);
    report("rcc_pllcfgr_reset", RCC_PLLCFGR);
    report("rcc_cfgr_reset", RCC_CFGR);
    report("rcc_ahb1enr_reset", RCC_AHB1ENR);
    report("rcc_apb1lpenr_reset", RCC_APB1LPENR);
    report("rcc_csr_reset", RCC_CSR);
    report("flash_acr_reset", FLASH_ACR);
    report("flash_cr_reset", FLASH_CR);
    report("pwr_cr_unclocked", PWR_CR); /* PWREN is off at reset */
    report("dwt_cyccnt_reset", DWT_CYCCNT);
}

/* CMSIS SystemInit (system_stm32f4xx.c): the FPU's access, the RCC to its reset state, the vector
   table in flash */
static void system_init(void)
{
    SCB_CPACR |= (3u << 20) | (3u << 22);
    RCC_CR |= RCC_CR_HSION;
    RCC_CFGR = 0;
    RCC_CR &= 0xFEF6FFFFu; /* HSEON, CSSON, PLLON off */
    RCC_PLLCFGR = 0x24003010u;
    RCC_CR &= 0xFFFBFFFFu; /* HSEBYP off */
    RCC_CIR = 0;
    SCB_VTOR = 0x08000000u;
    report("rcc_cr_system_init", RCC_CR);
}

static void clock_to_168mhz(void)
{
    /* a switch to a source that is not ready does not happen (RM0090 7.3.3: SWS) */
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_HSE;
    report("rcc_cfgr_sw_hse_off", RCC_CFGR);
    RCC_CFGR &= ~RCC_CFGR_SW;

    RCC_APB1ENR |= RCC_APB1ENR_PWREN;
    report("pwr_cr_clocked", PWR_CR);
    PWR_CR |= PWR_CR_VOS;

    RCC_CR |= RCC_CR_HSEON;
    uint32_t polls = 0;
    while (!(RCC_CR & RCC_CR_HSERDY)) {
        polls++;
    }
    report("hse_polls", polls);
    RCC_CFGR |= RCC_CFGR_PPRE2_DIV2 | RCC_CFGR_PPRE1_DIV4;
    RCC_PLLCFGR = 8u | (336u << 6) | (((2u >> 1) - 1u) << 16) | RCC_PLLCFGR_PLLSRC_HSE | (7u << 24);
    RCC_CR |= RCC_CR_PLLON;
    while (!(RCC_CR & RCC_CR_PLLRDY)) {
    }
    FLASH_ACR = FLASH_ACR_ICEN | FLASH_ACR_DCEN | FLASH_ACR_PRFTEN | FLASH_ACR_LATENCY_5WS;
    report("flash_acr", FLASH_ACR);
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC_CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL) {
    }
    report("rcc_cr_pll", RCC_CR);
    report("rcc_cfgr_pll", RCC_CFGR);
    report("rcc_pllcfgr", RCC_PLLCFGR);

    /* the PLL and the HSE under it cannot be stopped while they clock the system; the HSI can */
    RCC_CR &= ~(RCC_CR_PLLON | RCC_CR_HSEON | RCC_CR_HSION);
    report("rcc_cr_stop_all", RCC_CR);
}

static void flash_keys(void)
{
    FLASH_KEYR = 0x45670123u;
    FLASH_KEYR = 0xCDEF89ABu;
    report("flash_cr_unlocked", FLASH_CR);
    FLASH_CR = 1u << 31;
    report("flash_cr_relocked", FLASH_CR);
}

static void gpio(void)
{
    GPIO_MODER(PORT_D) = 0x55555555u; /* its clock is off: lost */
    report("gpiod_moder_unclocked", GPIO_MODER(PORT_D));
    RCC_AHB1ENR |= 0xFu; /* GPIOA..D */
    report("gpioa_moder_reset", GPIO_MODER(PORT_A));
    report("gpioa_pupdr_reset", GPIO_PUPDR(PORT_A));
    report("gpiob_moder_reset", GPIO_MODER(PORT_B));
    report("gpiob_ospeedr_reset", GPIO_OSPEEDR(PORT_B));
    report("gpiob_pupdr_reset", GPIO_PUPDR(PORT_B));
    report("gpiod_moder_reset", GPIO_MODER(PORT_D));

    /* PD12 push-pull output; PD0 input pulled up; PD1 open drain pulled up; PD2 analog pulled up */
    GPIO_MODER(PORT_D) = (1u << 24) | (0u << 0) | (1u << 2) | (3u << 4);
    GPIO_OTYPER(PORT_D) = 1u << 1;
    GPIO_PUPDR(PORT_D) = (1u << 0) | (1u << 2) | (1u << 4);
    GPIO_OSPEEDR(PORT_D) = 2u << 24;
    GPIO_AFRL(PORT_D) = 0x00000700u;
    GPIO_AFRH(PORT_D) = 0x00040000u;
    report("gpiod_moder", GPIO_MODER(PORT_D));
    report("gpiod_otyper", GPIO_OTYPER(PORT_D));
    report("gpiod_ospeedr", GPIO_OSPEEDR(PORT_D));
    report("gpiod_afrl", GPIO_AFRL(PORT_D));
    report("gpiod_afrh", GPIO_AFRH(PORT_D));
    report("gpiod_idr_start", GPIO_IDR(PORT_D));
    GPIO_BSRR(PORT_D) = (1u << 12) | (1u << 1);
    report("gpiod_odr_set", GPIO_ODR(PORT_D));
    report("gpiod_idr_set", GPIO_IDR(PORT_D));
    report("gpiod_bsrr_read", GPIO_BSRR(PORT_D));
    GPIO_BSRR(PORT_D) = 1u << (16 + 12);
    report("gpiod_odr_reset", GPIO_ODR(PORT_D));
    GPIO_BSRR(PORT_D) = (1u << 12) | (1u << (16 + 12));
    report("gpiod_odr_both", GPIO_ODR(PORT_D));
    GPIO_PUPDR(PORT_D) = 2u << 0; /* PD0 pulled down now, PD1 and PD2 float */
    report("gpiod_idr_pulldown", GPIO_IDR(PORT_D));
    uint32_t toggles = 0;
    for (int i = 0; i < 10; i++) {
        uint32_t before = GPIO_IDR(PORT_D) >> 12 & 1u;
        GPIO_ODR(PORT_D) ^= 1u << 12;
        toggles += (GPIO_IDR(PORT_D) >> 12 & 1u) != before;
    }
    report("gpiod_toggles", toggles);

    /* lock PD12's configuration (RM0090 8.4.8), then try to change PD12 and PD13 */
    GPIO_LCKR(PORT_D) = (1u << 16) | (1u << 12);
    GPIO_LCKR(PORT_D) = 1u << 12;
    GPIO_LCKR(PORT_D) = (1u << 16) | (1u << 12);
    report("gpiod_lckr_read1", GPIO_LCKR(PORT_D));
    report("gpiod_lckr_read2", GPIO_LCKR(PORT_D));
    GPIO_MODER(PORT_D) = 1u << 26; /* PD12 input, PD13 output: only PD13 changes */
    report("gpiod_moder_locked", GPIO_MODER(PORT_D));
    GPIO_LCKR(PORT_D) = 0;
    report("gpiod_lckr_after_clear", GPIO_LCKR(PORT_D));

    /* the peripheral reset (RCC_AHB1RSTR.GPIODRST) puts the port back to its reset state, lock included */
    RCC_AHB1RSTR |= 1u << PORT_D;
    RCC_AHB1RSTR &= ~(1u << PORT_D);
    report("gpiod_moder_after_reset", GPIO_MODER(PORT_D));
    report("gpiod_odr_after_reset", GPIO_ODR(PORT_D));
    report("gpiod_lckr_after_reset", GPIO_LCKR(PORT_D));
}

int main(void)
{
    clock_at_reset();
    system_init();
    DEMCR |= DEMCR_TRCENA;
    DWT_CYCCNT = 0;
    DWT_CTRL |= 1u; /* CYCCNTENA */
    time_spin("dwt_spin_hsi", "systick_spin_hsi");
    clock_to_168mhz();
    time_spin("dwt_spin_pll", "systick_spin_pll");
    flash_keys();
    gpio();
    put_text("done\n");
    return 0;
}
