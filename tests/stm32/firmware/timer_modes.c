/* The timer modes test firmware of the STM32 tier (tests/stm32/test_timers.py judges its reports
   against RM0090): TIM8 counting down with a repetition counter and MOE (PC6); ARR written mid-period
   with and without ARPE, and PSC, which waits for the update (TIM6); URS, UDIS and one-pulse mode
   (TIM7); PWM mode 2 and an inverted output (TIM4 channels 3 and 4 on PD14, PD15), through a change of
   the APB1 clock; toggle on match and forced levels (TIM9 on PE5, PE6); the timer clock with APB1
   undivided (TIM6); TIM1's complementary outputs (CH2N alone, CH3 with CH3N); TIM1's and TIM10's update
   interrupts sharing NVIC line 25. */
#include "timer_checks.h"

#define US(n) ((n) * (CORE_HZ / 1000000u)) /* core cycles */
#define MEASURE_LIMIT US(20000u)

static void wait_cycles(uint32_t cycles)
{
    uint32_t start = DWT_CYCCNT;
    while (DWT_CYCCNT - start < cycles) {
    }
}

static void report_pulse(uint32_t port, unsigned pin, const char *high_name, const char *period_name)
{
    uint32_t high, period;
    measure_pulse(port, pin, MEASURE_LIMIT, &high, &period);
    report(high_name, high);
    report(period_name, period);
}

static volatile uint32_t tim8_updates, tim1_updates, tim10_updates;

void tim8_up_tim13_handler(void)
{
    tim8_updates++;
    TIM_SR(TIM8_BASE) = ~TIM_SR_UIF;
}

/* TIM8 CH1: 1 us ticks (168 MHz / 168), down from ARR 999, PWM mode 1 (high while CNT <= CCR1 300),
   the update event every third period (RCR 2) */
static void advanced_down(void)
{
    pin_af(PORT_C, 6, 3);
    TIM_RCR(TIM8_BASE) = 2u;
    TIM_CCR(TIM8_BASE, 1) = 300u;
    TIM_CCMR1(TIM8_BASE) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(TIM8_BASE) = TIM_CCER_E(1);
    TIM_BDTR(TIM8_BASE) = TIM_BDTR_MOE;
    timer_start(TIM8_BASE, 167u, 999u, TIM_CR1_ARPE | TIM_CR1_DIR);
    TIM_DIER(TIM8_BASE) = TIM_DIER_UIE;
    report_pulse(PORT_C, 6, "tim8_down_high_cycles", "tim8_down_period_cycles");
    report("tim8_cr1", TIM_CR1(TIM8_BASE));
    NVIC_ISER(1) = 1u << (TIM8_UP_TIM13_IRQ - 32u);
    wait_cycles(US(30000u));
    NVIC_ICER(1) = 1u << (TIM8_UP_TIM13_IRQ - 32u);
    report("tim8_updates_30ms", tim8_updates);
    TIM_CR1(TIM8_BASE) = 0;
}

/* TIM6, 1 us ticks, ARR 1000: at CNT 100..199 ARR becomes 500; the cycles until the update */
static void arr_written_mid_period(uint32_t arpe, const char *cnt_name, const char *cycles_name)
{
    timer_start(TIM6_BASE, 83u, 1000u, arpe);
    while (TIM_CNT(TIM6_BASE) < 100u) {
    }
    uint32_t at = TIM_CNT(TIM6_BASE), start = DWT_CYCCNT;
    TIM_ARR(TIM6_BASE) = 500u;
    while (!(TIM_SR(TIM6_BASE) & TIM_SR_UIF)) {
    }
    uint32_t cycles = DWT_CYCCNT - start;
    TIM_CR1(TIM6_BASE) = 0;
    report(cnt_name, at);
    report(cycles_name, cycles);
}

/* TIM6 at 1 us ticks (PSC 83), ARR 999: PSC written as 167 in the middle of a period; the cycles from
   that update to the next two */
static void psc_preload(void)
{
    timer_start(TIM6_BASE, 83u, 999u, 0);
    while (TIM_CNT(TIM6_BASE) < 500u) {
    }
    uint32_t at = TIM_CNT(TIM6_BASE), written = DWT_CYCCNT;
    TIM_PSC(TIM6_BASE) = 167u;
    uint32_t updates[3];
    for (unsigned i = 0; i < 3; i++) {
        while (!(TIM_SR(TIM6_BASE) & TIM_SR_UIF)) {
        }
        TIM_SR(TIM6_BASE) = 0;
        updates[i] = DWT_CYCCNT;
    }
    TIM_CR1(TIM6_BASE) = 0;
    report("psc_cnt_at_write", at);
    report("psc_rest_of_period_cycles", updates[0] - written);
    report("psc_first_period_cycles", updates[1] - updates[0]);
    report("psc_second_period_cycles", updates[2] - updates[1]);
}

/* TIM7, 1 us ticks, ARR 99 */
static void update_control(void)
{
    TIM_PSC(TIM7_BASE) = 83u;
    TIM_ARR(TIM7_BASE) = 99u;
    TIM_CR1(TIM7_BASE) = TIM_CR1_URS;
    TIM_EGR(TIM7_BASE) = TIM_EGR_UG;
    report("tim7_sr_ug_with_urs", TIM_SR(TIM7_BASE));
    TIM_CR1(TIM7_BASE) = 0;
    TIM_EGR(TIM7_BASE) = TIM_EGR_UG;
    report("tim7_sr_ug", TIM_SR(TIM7_BASE));
    TIM_SR(TIM7_BASE) = 0;
    TIM_CR1(TIM7_BASE) = TIM_CR1_UDIS | TIM_CR1_CEN;
    wait_cycles(US(500u));
    report("tim7_sr_udis", TIM_SR(TIM7_BASE));
    TIM_CR1(TIM7_BASE) = TIM_CR1_CEN;
    wait_cycles(US(150u));
    report("tim7_sr_counting", TIM_SR(TIM7_BASE));
    TIM_CR1(TIM7_BASE) = 0;
    TIM_SR(TIM7_BASE) = 0;
    TIM_CNT(TIM7_BASE) = 0;
    TIM_CR1(TIM7_BASE) = TIM_CR1_OPM | TIM_CR1_CEN;
    wait_cycles(US(500u));
    report("tim7_cr1_one_pulse", TIM_CR1(TIM7_BASE));
    report("tim7_cnt_one_pulse", TIM_CNT(TIM7_BASE));
    report("tim7_sr_one_pulse", TIM_SR(TIM7_BASE));
}

/* TIM4, 1 us ticks, ARR 2040: CH3 PWM mode 2 with CCR3 500, CH4 PWM mode 1 inverted (CC4P) with CCR4
   300; then APB1 from HCLK / 4 to HCLK / 8: the timer clock from 84 to 42 MHz */
static void pwm2_polarity_and_clock(void)
{
    pin_af(PORT_D, 14, 2);
    pin_af(PORT_D, 15, 2);
    TIM_CCR(TIM4_BASE, 3) = 500u;
    TIM_CCR(TIM4_BASE, 4) = 300u;
    TIM_CCMR2(TIM4_BASE) = (TIM_CCMR_PWM2 | TIM_CCMR_OCPE) | ((TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << 8);
    TIM_CCER(TIM4_BASE) = TIM_CCER_E(3) | TIM_CCER_E(4) | TIM_CCER_P(4);
    timer_start(TIM4_BASE, 83u, 2040u, TIM_CR1_ARPE);
    report_pulse(PORT_D, 14, "pwm2_high_cycles", "pwm2_period_cycles");
    report_pulse(PORT_D, 15, "inverted_high_cycles", "inverted_period_cycles");
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_PPRE1) | RCC_CFGR_PPRE1_DIV8;
    report_pulse(PORT_D, 14, "pwm2_slow_high_cycles", "pwm2_slow_period_cycles");
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_PPRE1) | RCC_CFGR_PPRE1_DIV4;
    TIM_CR1(TIM4_BASE) = 0;
}

/* TIM9, 1 us ticks from 168 MHz, ARR 499: CH1 toggles at CNT 100 (PE5); CH2 forced high, then low (PE6) */
static void toggle_and_forced(void)
{
    pin_af(PORT_E, 5, 3);
    pin_af(PORT_E, 6, 3);
    TIM_CCR(TIM9_BASE, 1) = 100u;
    TIM_CCMR1(TIM9_BASE) = TIM_CCMR_TOGGLE | (TIM_CCMR_FORCE_HIGH << 8);
    TIM_CCER(TIM9_BASE) = TIM_CCER_E(1) | TIM_CCER_E(2);
    timer_start(TIM9_BASE, 167u, 499u, 0);
    report_pulse(PORT_E, 5, "toggle_high_cycles", "toggle_period_cycles");
    report("forced_high_pin", pin_level(PORT_E, 6));
    TIM_CCMR1(TIM9_BASE) = TIM_CCMR_TOGGLE | (TIM_CCMR_FORCE_LOW << 8);
    report("forced_low_pin", pin_level(PORT_E, 6));
    TIM_CR1(TIM9_BASE) = 0;
}

/* APB1 undivided (PPRE1 = /1, out of the chip's ratings but a valid setting): the timer clock is PCLK1
   itself, 168 MHz, not twice it; TIM6 at PSC 167 and ARR 999 then overflows every 1000 us */
static void apb_prescaler_one(void)
{
    RCC_CFGR &= ~RCC_CFGR_PPRE1;
    timer_start(TIM6_BASE, 167u, 999u, 0);
    uint32_t start = 0;
    for (unsigned i = 0; i < 2; i++) {
        while (!(TIM_SR(TIM6_BASE) & TIM_SR_UIF)) {
        }
        TIM_SR(TIM6_BASE) = 0;
        start = i == 0 ? DWT_CYCCNT : DWT_CYCCNT - start;
    }
    report("apb1_undivided_period_cycles", start);
    TIM_CR1(TIM6_BASE) = 0;
    RCC_CFGR |= RCC_CFGR_PPRE1_DIV4;
}

/* TIM1, 1 us ticks from 168 MHz, ARR 999, MOE: CH2N alone on PB0 (CC2NE, PWM mode 1, CCR2 300) and CH3
   with CH3N (PA10, PB1; CC3E and CC3NE, CCR3 400) */
static void complementary_outputs(void)
{
    pin_af(PORT_B, 0, 1);
    pin_af(PORT_B, 1, 1);
    pin_af(PORT_A, 10, 1);
    TIM_CCR(TIM1_BASE, 2) = 300u;
    TIM_CCR(TIM1_BASE, 3) = 400u;
    TIM_CCMR1(TIM1_BASE) = (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << 8;
    TIM_CCMR2(TIM1_BASE) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(TIM1_BASE) = TIM_CCER_NE(2) | TIM_CCER_E(3) | TIM_CCER_NE(3);
    TIM_BDTR(TIM1_BASE) = TIM_BDTR_MOE;
    timer_start(TIM1_BASE, 167u, 999u, TIM_CR1_ARPE);
    report_pulse(PORT_B, 0, "ch2n_high_cycles", "ch2n_period_cycles");
    report_pulse(PORT_A, 10, "ch3_high_cycles", "ch3_period_cycles");
    report_pulse(PORT_B, 1, "ch3n_high_cycles", "ch3n_period_cycles");
    TIM_CR1(TIM1_BASE) = 0;
    TIM_CCER(TIM1_BASE) = 0;
    TIM_BDTR(TIM1_BASE) = 0;
}

void tim1_up_tim10_handler(void)
{
    if (TIM_SR(TIM1_BASE) & TIM_SR_UIF) {
        tim1_updates++;
        TIM_SR(TIM1_BASE) = ~TIM_SR_UIF;
    }
    if (TIM_SR(TIM10_BASE) & TIM_SR_UIF) {
        tim10_updates++;
        TIM_SR(TIM10_BASE) = ~TIM_SR_UIF;
    }
}

/* TIM1 every 500 us and TIM10 every 300 us (1 us ticks from 168 MHz), both on NVIC line 25, for 30 ms */
static void shared_interrupt_line(void)
{
    timer_start(TIM1_BASE, 167u, 499u, 0);
    timer_start(TIM10_BASE, 167u, 299u, 0);
    TIM_DIER(TIM1_BASE) = TIM_DIER_UIE;
    TIM_DIER(TIM10_BASE) = TIM_DIER_UIE;
    NVIC_ISER(0) = 1u << TIM1_UP_TIM10_IRQ;
    wait_cycles(US(30000u));
    NVIC_ICER(0) = 1u << TIM1_UP_TIM10_IRQ;
    report("tim1_updates_30ms", tim1_updates);
    report("tim10_updates_30ms", tim10_updates);
}

int main(void)
{
    clock_168mhz();
    RCC_APB1ENR |= (1u << 2) | (1u << 4) | (1u << 5);               /* TIM4, TIM6, TIM7 */
    RCC_APB2ENR |= (1u << 0) | (1u << 1) | (1u << 16) | (1u << 17); /* TIM1, TIM8, TIM9, TIM10 */
    advanced_down();
    arr_written_mid_period(0, "arr_direct_cnt", "arr_direct_cycles");
    arr_written_mid_period(TIM_CR1_ARPE, "arr_preload_cnt", "arr_preload_cycles");
    psc_preload();
    update_control();
    pwm2_polarity_and_clock();
    toggle_and_forced();
    apb_prescaler_one();
    complementary_outputs();
    shared_interrupt_line();
    put_text("done\n");
    return 0;
}
