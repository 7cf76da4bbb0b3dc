/* The input capture test firmware of the STM32 tier, run with the machine's pins wired as
   -M rig-stm32f405,wires=PD12-PA0+PD13-PA6+PD1-PA7 (tests/stm32/test_timers.py):
   * PPM: TIM4 channel 1 (PD12) sends pulses whose widths its update interrupt changes each period
     (1000, 1500, 2000, 1200 us, CCR1 preloaded); TIM2 (84 MHz ticks, 32-bit) captures them on PA0,
     the rising edges on channel 1 (CC1S = 01), the falling ones on channel 2 from the same pin
     (CC2S = 10, CC2P = 1), in its interrupt;
   * both edges: TIM3 channel 1 (1 us ticks) captures TIM4 channel 2's 700 us pulses on PA6 with
     CC1P = CC1NP = 1;
   * a pin the firmware toggles itself (PD1, a rising edge every 500 us by DWT) captured by TIM3 channel 2
     on PA7, each edge and then every second one (IC2PSC);
   * PWM input mode: TIM3 reset by TI1's rising edges, CCR1 the period and CCR2 the high time;
   * trigger mode: TIM2 started by PA0's rising edge;
   * overcapture: edges left unread set CCxOF.
   Values go out as NAME=0xVALUE lines through semihosting. */
#include "timer_checks.h"

#define PULSES 10u
#define TIM2_IRQ 28u
#define TIM4_PERIOD_US 2041u
#define LIMIT (CORE_HZ / 20u) /* 50 ms */

static const uint16_t ppm_us[4] = { 1000u, 1500u, 2000u, 1200u };
static volatile uint32_t updates, rises[PULSES + 1], falls[PULSES + 1], n_rises, n_falls;

void tim4_handler(void)
{
    TIM_SR(TIM4_BASE) = ~TIM_SR_UIF;
    updates++;
    TIM_CCR(TIM4_BASE, 1) = ppm_us[updates % 4u]; /* preloaded: the period after next */
}

void tim2_handler(void)
{
    uint32_t sr = TIM_SR(TIM2_BASE);
    if ((sr & TIM_SR_CCIF(1)) && n_rises <= PULSES) {
        rises[n_rises++] = TIM_CCR(TIM2_BASE, 1); /* the read clears CC1IF */
    }
    if ((sr & TIM_SR_CCIF(2)) && n_falls <= PULSES) {
        falls[n_falls++] = TIM_CCR(TIM2_BASE, 2);
    }
    TIM_SR(TIM2_BASE) = ~(TIM_SR_CCIF(1) | TIM_SR_CCIF(2)); /* (past PULSES the flags only) */
}

static void capture_setup(void)
{
    RCC_APB1ENR |= 0x7u; /* TIM2, TIM3, TIM4 */
    pin_af(PORT_D, 12, 2);
    pin_af(PORT_D, 13, 2);
    pin_af(PORT_A, 0, 1);
    pin_af(PORT_A, 6, 2);
    pin_af(PORT_A, 7, 2);
    RCC_AHB1ENR |= 1u << PORT_D;
    GPIO_MODER(PORT_D) = (GPIO_MODER(PORT_D) & ~(3u << 2)) | (1u << 2); /* PD1 output */

    TIM_CCMR1(TIM2_BASE) = TIM_CCMR_IC_TI_OWN | (TIM_CCMR_IC_TI_OTHER << 8);
    TIM_CCER(TIM2_BASE) = TIM_CCER_E(1) | TIM_CCER_E(2) | TIM_CCER_P(2);
    TIM_ARR(TIM2_BASE) = 0xFFFFFFFFu;
    TIM_DIER(TIM2_BASE) = TIM_DIER_CCIE(1) | TIM_DIER_CCIE(2);
    TIM_EGR(TIM2_BASE) = TIM_EGR_UG;
    TIM_SR(TIM2_BASE) = 0;
    TIM_CR1(TIM2_BASE) = TIM_CR1_CEN;

    TIM_PSC(TIM3_BASE) = 83u;
    TIM_ARR(TIM3_BASE) = 0xFFFFu;
    TIM_CCMR1(TIM3_BASE) = TIM_CCMR_IC_TI_OWN | (TIM_CCMR_IC_TI_OWN << 8);
    TIM_CCER(TIM3_BASE) = TIM_CCER_E(1) | TIM_CCER_P(1) | (8u << 0) | TIM_CCER_E(2); /* CC1NP: both */
    TIM_EGR(TIM3_BASE) = TIM_EGR_UG;
    TIM_SR(TIM3_BASE) = 0;
    TIM_CR1(TIM3_BASE) = TIM_CR1_CEN;
}

static void ppm(void)
{
    TIM_PSC(TIM4_BASE) = 83u;
    TIM_ARR(TIM4_BASE) = TIM4_PERIOD_US - 1u;
    TIM_CCR(TIM4_BASE, 1) = ppm_us[0];
    TIM_CCR(TIM4_BASE, 2) = 700u;
    TIM_CCMR1(TIM4_BASE) = (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) | ((TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << 8);
    TIM_CR1(TIM4_BASE) = TIM_CR1_ARPE;
    TIM_EGR(TIM4_BASE) = TIM_EGR_UG;
    TIM_SR(TIM4_BASE) = 0;
    TIM_DIER(TIM4_BASE) = TIM_DIER_UIE;
    NVIC_ISER(0) = (1u << TIM2_IRQ) | (1u << TIM4_IRQ);
    TIM_CCER(TIM4_BASE) = TIM_CCER_E(1) | TIM_CCER_E(2);
    TIM_CR1(TIM4_BASE) |= TIM_CR1_CEN;

    uint32_t start = DWT_CYCCNT;
    while (n_falls <= PULSES && DWT_CYCCNT - start < LIMIT) {
    }
    NVIC_ICER(0) = 1u << TIM2_IRQ;
    report("ppm_captures", n_falls);
    for (unsigned i = 0; i < PULSES; i++) {
        char name[] = "ppm_width_0";
        name[10] = (char)('0' + i);
        report(name, falls[i] - rises[i]);
        char period[] = "ppm_period_0";
        period[11] = (char)('0' + i);
        report(period, rises[i + 1] - rises[i]);
    }
}

/* TIM3 channel 1: both edges of PD13's pulses, the intervals between four successive captures */
static void both_edges(void)
{
    uint32_t last = 0;
    for (unsigned i = 0; i < 5; i++) {
        uint32_t start = DWT_CYCCNT;
        while (!(TIM_SR(TIM3_BASE) & TIM_SR_CCIF(1)) && DWT_CYCCNT - start < LIMIT) {
        }
        uint32_t at = TIM_CCR(TIM3_BASE, 1);
        if (i == 0) {
            report("tim3_sr_after_ccr_read", TIM_SR(TIM3_BASE) & TIM_SR_CCIF(1));
        } else {
            char name[] = "edge_interval_0";
            name[14] = (char)('0' + i);
            report(name, (at - last) & 0xFFFFu);
        }
        last = at;
    }
}

/* @count rising edges on PD1, one every 500 us (by DWT), then TIM3's last capture on channel 2 */
static uint32_t rising_edges(unsigned count)
{
    for (unsigned i = 0; i < count; i++) {
        uint32_t start = DWT_CYCCNT;
        GPIO_BSRR(PORT_D) = 1u << 1;
        while (DWT_CYCCNT - start < CORE_HZ / 4000u) { /* 250 us */
        }
        GPIO_BSRR(PORT_D) = 1u << (16 + 1);
        while (DWT_CYCCNT - start < CORE_HZ / 2000u) {
        }
    }
    return TIM_CCR(TIM3_BASE, 2);
}

/* TIM3 channel 2 captures PD1's rising edges, which the firmware makes: each one, then (IC2PSC = 01,
   set while CC2E is off) every second one */
static void toggled_pin(void)
{
    uint32_t first = rising_edges(1);
    report("toggle_interval_us", (rising_edges(1) - first) & 0xFFFFu);
    TIM_CCER(TIM3_BASE) &= ~TIM_CCER_E(2);
    TIM_CCMR1(TIM3_BASE) |= TIM_CCMR_ICPSC_DIV2 << 8;
    TIM_CCER(TIM3_BASE) |= TIM_CCER_E(2);
    first = rising_edges(2);
    report("toggle_interval_div2_us", (rising_edges(2) - first) & 0xFFFFu);
    report("toggle_one_more_edge_us", (rising_edges(1) - first) & 0xFFFFu);
}

/* TIM3 in the PWM input mode of RM0090 18.3.6 on PA6 (TIM4 CH2's 700 us of 2041): IC1 on TI1's rising
   edges, IC2 on its falling ones, and TI1FP1 resetting the counter (SMCR: TS = 101, SMS = 100), so CCR1
   is the period and CCR2 the high time */
static void pwm_input_mode(void)
{
    TIM_CCER(TIM3_BASE) = 0;
    TIM_CCMR1(TIM3_BASE) = TIM_CCMR_IC_TI_OWN | (TIM_CCMR_IC_TI_OTHER << 8);
    TIM_CCER(TIM3_BASE) = TIM_CCER_E(1) | TIM_CCER_E(2) | TIM_CCER_P(2);
    TIM_SMCR(TIM3_BASE) = (5u << 4) | 4u;
    TIM_SR(TIM3_BASE) = 0;
    uint32_t period = 0;
    for (unsigned i = 0; i < 3; i++) { /* (the first capture ends a period the reset did not start) */
        uint32_t start = DWT_CYCCNT;
        while (!(TIM_SR(TIM3_BASE) & TIM_SR_CCIF(1)) && DWT_CYCCNT - start < LIMIT) {
        }
        period = TIM_CCR(TIM3_BASE, 1);
    }
    report("pwm_input_period_us", period);
    report("pwm_input_high_us", TIM_CCR(TIM3_BASE, 2));
    report("pwm_input_sr", TIM_SR(TIM3_BASE) & TIM_SR_TIF);
    TIM_SMCR(TIM3_BASE) = 0;
}

/* TIM2 stopped, in trigger mode on TI1FP1 (SMCR: TS = 101, SMS = 110): PA0's next rising edge starts it */
static void trigger_mode(void)
{
    TIM_CR1(TIM2_BASE) = 0;
    TIM_CNT(TIM2_BASE) = 0;
    TIM_SMCR(TIM2_BASE) = (5u << 4) | 6u;
    TIM_SR(TIM2_BASE) = 0;
    report("trigger_cr1_before", TIM_CR1(TIM2_BASE));
    uint32_t start = DWT_CYCCNT;
    while (!(TIM_CR1(TIM2_BASE) & TIM_CR1_CEN) && DWT_CYCCNT - start < LIMIT) {
    }
    report("trigger_cr1_after", TIM_CR1(TIM2_BASE));
    report("trigger_sr", TIM_SR(TIM2_BASE) & TIM_SR_TIF);
    TIM_SMCR(TIM2_BASE) = 0;
}

/* Three TIM4 periods with TIM2's flags unread: each channel captured again over its set flag */
static void overcapture(void)
{
    TIM_SR(TIM2_BASE) = 0;
    uint32_t start = DWT_CYCCNT;
    while (DWT_CYCCNT - start < 3u * TIM4_PERIOD_US * (CORE_HZ / 1000000u)) {
    }
    report("tim2_sr_unread", TIM_SR(TIM2_BASE));
}

int main(void)
{
    clock_168mhz();
    capture_setup();
    ppm();
    both_edges();
    toggled_pin();
    pwm_input_mode();
    trigger_mode();
    overcapture();
    put_text("done\n");
    return 0;
}
