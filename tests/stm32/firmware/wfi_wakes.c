/* Wake-ups from WFI at a timer's update events (tests/stm32/test_wfi_wakes.py): TIM2 counts at the 84 MHz
   APB1 timer clock with ARR 8399, an update every 100 us (16 800 core cycles); the core sleeps in WFI
   between them. Each interrupt's entry is DWT_CYCCNT less the first's and its multiple of the period: under
   icount the same for every one, whatever the host does meanwhile. Each handler then runs a different
   number of instructions before the core sleeps again, so the instants the core halts at vary. */
#include "timer_checks.h"

#define WAKES 2000u
#define PERIOD_CYCLES 16800u
#define TIM2_IRQ 28u

static volatile uint32_t wakes;
static uint32_t first, late_min = 0xFFFFFFFFu, late_max;

void tim2_handler(void);
void tim2_handler(void)
{
    uint32_t now = DWT_CYCCNT, k = wakes;
    TIM_SR(TIM2_BASE) = 0;
    if (k == 0) {
        first = now;
    } else {
        uint32_t late = now - first - k * PERIOD_CYCLES;
        late_min = late < late_min ? late : late_min;
        late_max = late > late_max ? late : late_max;
    }
    for (volatile uint32_t spin = (k * 7u) % 53u; spin > 0; spin--) {
    }
    wakes = k + 1;
}

int main(void)
{
    clock_168mhz();
    RCC_APB1ENR |= 1u << 0; /* TIM2 */
    TIM_DIER(TIM2_BASE) = TIM_DIER_UIE;
    NVIC_ISER(TIM2_IRQ / 32u) = 1u << (TIM2_IRQ % 32u);
    timer_start(TIM2_BASE, 0u, PERIOD_CYCLES / 2u - 1u, 0u);
    while (wakes < WAKES) {
        __asm volatile("wfi");
    }
    report("wakes", wakes);
    report("late_min", late_min);
    report("late_max", late_max);
    put_text("done\n");
    return 0;
}
