/* The window watchdog test firmware of the STM32 tier (RM0090 section 20), at the 16 MHz HSI (PCLK1 16 MHz):
   WWDG's registers at reset and without its clock; the counter with WDGTB = 3 (a count every 4096 * 8
   PCLK1 cycles), EWI and the window open, refreshed from the early wakeup interrupt four times (each
   interrupt's time by DWT_CYCCNT); then a window closed to W = 0x50 and a refresh above it: a reset.
   Its second boot starts the watchdog and stops refreshing; its third reports when the reset came (the
   cycles the second boot's loop kept in RAM that a reset keeps) and the reset flags each time. */
#include "semihost.h"
#include "stm32f405.h"

#define POWER_ON_FLAGS 0x0E000000u
#define RCC_CSR_FLAGS 0xFE000000u
#define WWDG_IRQ 0u
#define WDGA (1u << 7)
#define CFR_WDGTB_8 (3u << 7)
#define CFR_EWI (1u << 9)
#define WINDOW 0x50u
#define REFRESHES 3u

static volatile uint32_t wakeups, wakeup_at[REFRESHES + 1u];
/* kept through resets: which boot this is, and the second boot's times */
static volatile uint32_t boot __attribute__((section(".noinit")));
static volatile uint32_t started_at __attribute__((section(".noinit")));
static volatile uint32_t alive_at __attribute__((section(".noinit")));

void wwdg_handler(void);
void wwdg_handler(void)
{
    wakeup_at[wakeups] = DWT_CYCCNT;
    WWDG_SR = 0; /* EWIF: write 0 to clear */
    wakeups++;
    WWDG_CR = WDGA | 0x7Fu;
}

__attribute__((noinline)) static void starve(void)
{
    for (;;) {
        alive_at = DWT_CYCCNT;
    }
}

static void first_boot(void)
{
    RCC_CSR |= RCC_CSR_RMVF;
    DWT_CTRL |= 1u;
    report("cr_unclocked", WWDG_CR);
    RCC_APB1ENR |= RCC_APB1ENR_WWDGEN;
    report("cr_reset", WWDG_CR);
    report("cfr_reset", WWDG_CFR);
    report("sr_reset", WWDG_SR);
    WWDG_CFR = CFR_EWI | CFR_WDGTB_8 | 0x7Fu;
    NVIC_ISER(0) = 1u << WWDG_IRQ;
    uint32_t start = DWT_CYCCNT;
    WWDG_CR = WDGA | 0x7Fu;
    while (wakeups <= REFRESHES) {
        __asm volatile("wfi");
    }
    report("cr_running", WWDG_CR & WDGA);
    for (unsigned i = 0; i <= REFRESHES; i++) {
        char name[] = "wakeup_0";
        name[7] = (char)('0' + i);
        report(name, wakeup_at[i] - start);
    }
    boot = 2u;
    WWDG_CFR = CFR_WDGTB_8 | WINDOW; /* (EWI stays: only a reset clears it) */
    report("cfr_window", WWDG_CFR);
    WWDG_CR = WDGA | 0x7Fu; /* the counter is above the window: a reset */
    put_text("not reset\n");
    exit_with(1);
}

static void second_boot(uint32_t flags)
{
    report("boot2_csr", flags);
    report("boot2_cr", WWDG_CR);
    RCC_CSR |= RCC_CSR_RMVF;
    boot = 3u;
    DWT_CTRL |= 1u;
    RCC_APB1ENR |= RCC_APB1ENR_WWDGEN;
    WWDG_CFR = CFR_WDGTB_8 | 0x7Fu;
    WWDG_CR = WDGA | 0x7Fu;
    started_at = DWT_CYCCNT;
    starve();
}

int main(void)
{
    uint32_t flags = RCC_CSR & RCC_CSR_FLAGS;
    if (flags == POWER_ON_FLAGS) {
        first_boot();
    }
    if (boot == 2u) {
        second_boot(flags);
    }
    report("boot3_csr", flags);
    report("reset_after_cycles", alive_at - started_at);
    put_text("done\n");
    return 0;
}
