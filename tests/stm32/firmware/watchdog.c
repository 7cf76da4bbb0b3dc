/* The watchdog test firmware of the STM32 tier (RM0090 section 19, the IWDG), at the 16 MHz HSI: IWDG's
   registers at reset, PR written without the 0x5555 key (ignored), PR and RLR written with it and their
   update flags (PVU, RVU) timed with DWT_CYCCNT, a write during an update (ignored); then the IWDG
   started with a 50 ms timeout and refreshed at SysTick's ticks (10 ms) 40 times (the core asleep between SysTick's
   ticks), then left to run out: a loop keeps DWT_CYCCNT in RAM that a reset keeps. Its second boot
   (RCC_CSR's reset flags tell it) reports the flags and the cycles from the last refresh to the reset. */
#include "semihost.h"
#include "stm32f405.h"

#define RCC_CSR_FLAGS 0xFE000000u
#define POWER_ON_FLAGS 0x0E000000u /* PORRSTF, PINRSTF, BORRSTF */
#define KEY_ACCESS 0x5555u
#define KEY_RELOAD 0xAAAAu
#define KEY_START 0xCCCCu
#define IWDG_SR_PVU (1u << 0)
#define IWDG_SR_RVU (1u << 1)
#define HSI_HZ 16000000u
#define TIMEOUT_PR 1u                  /* LSI / 8 */
#define TIMEOUT_RLR 199u               /* 200 ticks of 8 LSI cycles: 50 ms */
#define REFRESH_CYCLES (HSI_HZ / 100u) /* SysTick's reload: a tick every 10 ms or so */
#define REFRESHES 40u

/* kept through the reset */
static volatile uint32_t refreshed_at __attribute__((section(".noinit")));
static volatile uint32_t alive_at __attribute__((section(".noinit")));

/* the cycles PVU or RVU stays set after a write */
static uint32_t update_cycles(uint32_t flag)
{
    uint32_t start = DWT_CYCCNT;
    while (IWDG_SR & flag) {
    }
    return DWT_CYCCNT - start;
}

static volatile uint32_t ticks;

void systick_handler(void);
void systick_handler(void) { ticks++; }

/* The core asleep until SysTick's next tick */
static void sleep_tick(void)
{
    uint32_t seen = ticks;
    while (ticks == seen) {
        __asm volatile("wfi");
    }
}

/* No more refreshes: the loop the watchdog's reset interrupts */
__attribute__((noinline)) static void starve(void)
{
    for (;;) {
        alive_at = DWT_CYCCNT;
    }
}

static void first_boot(void)
{
    RCC_CSR |= RCC_CSR_RMVF;
    DWT_CTRL |= 1u; /* CYCCNTENA */
    report("iwdg_pr_reset", IWDG_PR);
    report("iwdg_rlr_reset", IWDG_RLR);
    report("iwdg_sr_reset", IWDG_SR);
    IWDG_PR = 5u;
    report("pr_without_key", IWDG_PR);
    IWDG_KR = KEY_ACCESS;
    IWDG_PR = TIMEOUT_PR;
    IWDG_PR = 6u; /* during the update: ignored */
    report("pvu_cycles", update_cycles(IWDG_SR_PVU));
    IWDG_RLR = TIMEOUT_RLR;
    report("rvu_cycles", update_cycles(IWDG_SR_RVU));
    report("iwdg_pr", IWDG_PR);
    report("iwdg_rlr", IWDG_RLR);
    report("starve_pc", (uint32_t)(uintptr_t)starve & ~1u);

    SYST_RVR = REFRESH_CYCLES - 1u;
    SYST_CVR = 0;
    SYST_CSR = SYST_CSR_ENABLE_TICKINT_CORE;
    IWDG_KR = KEY_START;
    uint32_t started = DWT_CYCCNT, longest = 0, last = started;
    for (unsigned i = 0; i < REFRESHES; i++) {
        sleep_tick();
        IWDG_KR = KEY_RELOAD;
        uint32_t now = DWT_CYCCNT;
        longest = now - last > longest ? now - last : longest;
        last = now;
    }
    SYST_CSR = 0;
    report("refreshed", REFRESHES);
    report("refreshed_for_cycles", last - started);
    report("longest_refresh_gap", longest);
    IWDG_KR = KEY_RELOAD;
    refreshed_at = DWT_CYCCNT;
    starve();
}

int main(void)
{
    uint32_t flags = RCC_CSR & RCC_CSR_FLAGS;
    if (flags == POWER_ON_FLAGS) {
        first_boot();
    }
    report("boot2_csr", flags);
    report("reset_after_cycles", alive_at - refreshed_at);
    report("boot2_iwdg_pr", IWDG_PR);
    put_text("done\n");
    return 0;
}
