/* The timers' test firmware of the STM32 tier (tests/stm32/test_timers.py judges its reports against
   RM0090): register reset values and writable bits of TIM1..TIM14, clock gating and the RCC reset;
   TIM4 channel 1 as a 490 Hz ESC PWM on PD12 (1 us ticks from the 84 MHz APB1 timer clock); TIM1
   channel 1 as OneShot125 on PA8 (8 MHz ticks from the 168 MHz APB2 timer clock), silent until
   BDTR.MOE; update and compare interrupts counted over a DWT-timed window; CCR preload (OCxPE) seen on
   TIM4 channel 2's pin PD13; TIM3 counting center-aligned on PB0 (channel 3). Every pin is measured by
   polling its IDR against DWT_CYCCNT. */
#include "timer_checks.h"

#define PWM_PSC 83u   /* 84 MHz / 84: 1 us */
#define PWM_ARR 2040u /* 2041 us: 490 Hz */
#define PWM_CCR 1500u
#define ONESHOT_PSC 20u               /* 168 MHz / 21: 8 MHz */
#define ONESHOT_ARR 3999u             /* 500 us */
#define ONESHOT_CCR 1500u             /* 187.5 us: half throttle in OneShot125 */
#define WINDOW_CYCLES (CORE_HZ / 10u) /* 100 ms */
#define MEASURE_LIMIT (CORE_HZ / 50u) /* 20 ms: ten ESC periods */

static const uint32_t timer_bases[15] = {
    0,         TIM1_BASE, TIM2_BASE,  TIM3_BASE,  TIM4_BASE,  TIM5_BASE,  TIM6_BASE,  TIM7_BASE,
    TIM8_BASE, TIM9_BASE, TIM10_BASE, TIM11_BASE, TIM12_BASE, TIM13_BASE, TIM14_BASE,
};

static void report_indexed(const char *prefix, unsigned index, const char *suffix, uint32_t value)
{
    char name[40];
    unsigned n = 0;
    while (*prefix) {
        name[n++] = *prefix++;
    }
    if (index >= 10) {
        name[n++] = (char)('0' + index / 10);
    }
    name[n++] = (char)('0' + index % 10);
    while (*suffix && n < sizeof name - 1) {
        name[n++] = *suffix++;
    }
    name[n] = '\0';
    report(name, value);
}

static void reset_values(void)
{
    TIM_CR1(TIM4_BASE) = TIM_CR1_ARPE; /* its clock is off: lost */
    report("tim4_cr1_unclocked", TIM_CR1(TIM4_BASE));
    RCC_APB1ENR |= 0x1FFu;                             /* TIM2..TIM7, TIM12..TIM14 */
    RCC_APB2ENR |= (1u << 0) | (1u << 1) | (7u << 16); /* TIM1, TIM8, TIM9..TIM11 */
    for (unsigned t = 1; t <= 14; t++) {
        uint32_t base = timer_bases[t], any = 0;
        for (uint32_t offset = 0; offset <= 0x50u; offset += 4) {
            any |= REG(base + offset);
        }
        report_indexed("tim", t, "_or_of_registers", any);
        TIM_DIER(base) = 0xFFFFFFFFu;
        report_indexed("tim", t, "_dier_ones", TIM_DIER(base));
        TIM_DIER(base) = 0;
        TIM_CR1(base) = 0xFFFFFFFEu; /* all but CEN */
        report_indexed("tim", t, "_cr1_ones", TIM_CR1(base));
        TIM_CR1(base) = 0;
        TIM_CCER(base) = 0xFFFFFFFFu;
        report_indexed("tim", t, "_ccer_ones", TIM_CCER(base));
        TIM_CCER(base) = 0;
        TIM_ARR(base) = 0xFFFFFFFFu;
        report_indexed("tim", t, "_arr_ones", TIM_ARR(base));
        TIM_ARR(base) = 0;
        TIM_CR2(base) = 0xFFFFFFFFu;
        report_indexed("tim", t, "_cr2_ones", TIM_CR2(base));
        TIM_CR2(base) = 0;
        REG(base + 0x50u) = 0xFFFFFFFFu; /* OR */
        report_indexed("tim", t, "_or_ones", REG(base + 0x50u));
        REG(base + 0x50u) = 0;
    }
}

/* Channel 1 of the timer at @base in PWM mode 1, PSC, ARR (under ARPE) and CCR1 (under OC1PE) taken by
   UG into the shadow registers, the output enabled */
static void pwm_channel1(uint32_t base, uint32_t psc, uint32_t arr, uint32_t ccr)
{
    TIM_PSC(base) = psc;
    TIM_ARR(base) = arr;
    TIM_CCR(base, 1) = ccr;
    TIM_CCMR1(base) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(base) = TIM_CCER_E(1);
    TIM_CR1(base) = TIM_CR1_ARPE;
    TIM_EGR(base) = TIM_EGR_UG;
}

static void tim4_pwm(void)
{
    pin_af(PORT_D, 12, 2);
    pwm_channel1(TIM4_BASE, PWM_PSC, PWM_ARR, PWM_CCR);
    report("tim4_sr_after_ug", TIM_SR(TIM4_BASE));
    TIM_SR(TIM4_BASE) = 0;
    TIM_CR1(TIM4_BASE) |= TIM_CR1_CEN;
    uint32_t high, period;
    measure_pulse(PORT_D, 12, MEASURE_LIMIT, &high, &period);
    report("tim4_high_cycles", high);
    report("tim4_period_cycles", period);
    report("tim4_psc", TIM_PSC(TIM4_BASE));
    report("tim4_arr", TIM_ARR(TIM4_BASE));
    report("tim4_ccr1", TIM_CCR(TIM4_BASE, 1));
}

static void tim1_oneshot125(void)
{
    pin_af(PORT_A, 8, 1);
    pwm_channel1(TIM1_BASE, ONESHOT_PSC, ONESHOT_ARR, ONESHOT_CCR);
    TIM_CR1(TIM1_BASE) |= TIM_CR1_CEN;
    uint32_t high, period;
    measure_pulse(PORT_A, 8, CORE_HZ / 500u, &high, &period); /* no MOE: the output stays off */
    report("tim1_high_without_moe", high);
    TIM_BDTR(TIM1_BASE) = TIM_BDTR_MOE;
    measure_pulse(PORT_A, 8, MEASURE_LIMIT, &high, &period);
    report("tim1_high_cycles", high);
    report("tim1_period_cycles", period);
    report("tim1_bdtr", TIM_BDTR(TIM1_BASE));
}

static volatile uint32_t tim4_updates, tim4_compares, tim1_updates, tim1_compares;

void tim4_handler(void)
{
    uint32_t sr = TIM_SR(TIM4_BASE);
    tim4_updates += sr & TIM_SR_UIF ? 1u : 0u;
    tim4_compares += sr & TIM_SR_CCIF(1) ? 1u : 0u;
    TIM_SR(TIM4_BASE) = ~sr; /* rc_w0: zeros clear the flags seen, ones leave the rest */
}

void tim1_up_tim10_handler(void)
{
    tim1_updates++;
    TIM_SR(TIM1_BASE) = ~TIM_SR_UIF;
}

void tim1_cc_handler(void)
{
    tim1_compares++;
    TIM_SR(TIM1_BASE) = ~TIM_SR_CCIF(1);
}

static void interrupts(void)
{
    TIM_SR(TIM4_BASE) = 0;
    TIM_SR(TIM1_BASE) = 0;
    TIM_DIER(TIM4_BASE) = TIM_DIER_UIE | TIM_DIER_CCIE(1);
    TIM_DIER(TIM1_BASE) = TIM_DIER_UIE | TIM_DIER_CCIE(1);
    NVIC_ISER(0) = (1u << TIM1_UP_TIM10_IRQ) | (1u << TIM1_CC_IRQ) | (1u << TIM4_IRQ);
    uint32_t start = DWT_CYCCNT;
    while (DWT_CYCCNT - start < WINDOW_CYCLES) {
    }
    NVIC_ICER(0) = (1u << TIM1_UP_TIM10_IRQ) | (1u << TIM1_CC_IRQ) | (1u << TIM4_IRQ);
    TIM_DIER(TIM4_BASE) = 0;
    TIM_DIER(TIM1_BASE) = 0;
    report("tim4_update_interrupts", tim4_updates);
    report("tim4_compare_interrupts", tim4_compares);
    report("tim1_update_interrupts", tim1_updates);
    report("tim1_compare_interrupts", tim1_compares);
}

static void wait_count_between(uint32_t base, uint32_t from, uint32_t to)
{
    uint32_t cnt;
    do {
        cnt = TIM_CNT(base);
    } while (cnt < from || cnt >= to);
}

/* TIM4 channel 2 (PD13), CCR2 1000 us, written to 200 us in the middle of a period (CNT 500 us) */
static void preload(uint32_t ocpe, const char *pin_name, const char *high_name, const char *ccr_name)
{
    TIM_CCMR1(TIM4_BASE) = (TIM_CCMR1(TIM4_BASE) & 0x00FFu) | ((TIM_CCMR_PWM1 | ocpe) << 8);
    TIM_CCR(TIM4_BASE, 2) = 1000u;
    TIM_EGR(TIM4_BASE) = TIM_EGR_UG;
    wait_count_between(TIM4_BASE, 500u, 600u);
    TIM_CCR(TIM4_BASE, 2) = 200u;
    report(pin_name, pin_level(PORT_D, 13));
    report(ccr_name, TIM_CCR(TIM4_BASE, 2));
    uint32_t high, period;
    measure_pulse(PORT_D, 13, MEASURE_LIMIT, &high, &period);
    report(high_name, high);
}

static void preloads(void)
{
    pin_af(PORT_D, 13, 2);
    TIM_CCER(TIM4_BASE) |= TIM_CCER_E(2);
    preload(TIM_CCMR_OCPE, "preload_pin_after_write", "preload_high_next", "preload_ccr_read");
    preload(0, "direct_pin_after_write", "direct_high_next", "direct_ccr_read");
}

/* TIM3 channel 3 on PB0, center-aligned mode 1: PSC 83 (1 us), ARR 1000, CCR3 250, PWM mode 1 */
static void center_aligned(void)
{
    pin_af(PORT_B, 0, 2);
    TIM_PSC(TIM3_BASE) = PWM_PSC;
    TIM_ARR(TIM3_BASE) = 1000u;
    TIM_CCR(TIM3_BASE, 3) = 250u;
    TIM_CCMR2(TIM3_BASE) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(TIM3_BASE) = TIM_CCER_E(3);
    TIM_CR1(TIM3_BASE) = TIM_CR1_ARPE | TIM_CR1_CMS_CENTER1;
    TIM_EGR(TIM3_BASE) = TIM_EGR_UG;
    TIM_CR1(TIM3_BASE) |= TIM_CR1_CEN;
    uint32_t high, period;
    measure_pulse(PORT_B, 0, MEASURE_LIMIT, &high, &period);
    report("tim3_center_high_cycles", high);
    report("tim3_center_period_cycles", period);
    TIM_CR1(TIM3_BASE) = 0;
}

static void rcc_reset(void)
{
    RCC_APB1RSTR |= 1u << 2; /* TIM4RST */
    RCC_APB1RSTR &= ~(1u << 2);
    report("tim4_arr_after_reset", TIM_ARR(TIM4_BASE));
    report("tim4_cr1_after_reset", TIM_CR1(TIM4_BASE));
    report("tim4_ccer_after_reset", TIM_CCER(TIM4_BASE));
}

int main(void)
{
    reset_values();
    clock_168mhz();
    tim4_pwm();
    tim1_oneshot125();
    interrupts();
    preloads();
    center_aligned();
    rcc_reset();
    put_text("done\n");
    return 0;
}
