/* The STM32 tier's pulse-reading test firmware: four motors' pulses on TIM4 (490 Hz, 1 us ticks from the
   84 MHz APB1 timer clock: 1000, 1250, 1500 and 2000 us on PD12..PD15) and a OneShot125 pulse on TIM1
   channel 1 (8 MHz ticks from 168 MHz, 187.5 us every 500 us, PA8), then "ready" and a spin that never
   ends: tests/stm32/test_timers.py reads the latched pulses from outside, over QEMU's QMP. */
#include "timer_checks.h"

static const uint32_t motor_us[4] = { 1000u, 1250u, 1500u, 2000u };

int main(void)
{
    clock_168mhz();
    RCC_APB1ENR |= 1u << 2; /* TIM4 */
    RCC_APB2ENR |= 1u << 0; /* TIM1 */
    for (unsigned ch = 1; ch <= 4; ch++) {
        pin_af(PORT_D, 11 + ch, 2);
        TIM_CCR(TIM4_BASE, ch) = motor_us[ch - 1];
    }
    TIM_CCMR1(TIM4_BASE) = (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) * 0x0101u;
    TIM_CCMR2(TIM4_BASE) = (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) * 0x0101u;
    TIM_CCER(TIM4_BASE) = TIM_CCER_E(1) | TIM_CCER_E(2) | TIM_CCER_E(3) | TIM_CCER_E(4);
    timer_start(TIM4_BASE, 83u, 2040u, TIM_CR1_ARPE);

    pin_af(PORT_A, 8, 1);
    TIM_CCR(TIM1_BASE, 1) = 1500u;
    TIM_CCMR1(TIM1_BASE) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(TIM1_BASE) = TIM_CCER_E(1);
    TIM_BDTR(TIM1_BASE) = TIM_BDTR_MOE;
    timer_start(TIM1_BASE, 20u, 3999u, TIM_CR1_ARPE);

    put_text("ready\n");
    for (;;) {
    }
}
