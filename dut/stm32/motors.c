/* The motor outputs (motors.h): PWM mode 1 with CCR preloaded (OCxPE) and ARR preloaded (ARPE), so a
   new pulse takes effect at the next update event and never makes a runt pulse (RM0090 18.3.9). */
#include "motors.h"

#include "board.h"
#include "stm32f405.h"

/* motor i on TIMER[i] channel CHANNEL[i] (board.h) */
static const uint32_t timer[4] = { TIM3_BASE, TIM3_BASE, TIM2_BASE, TIM2_BASE };
static const uint8_t channel[4] = { 3, 4, 4, 3 };

static void pin_af(uint32_t port, unsigned pin, unsigned af)
{
    RCC_AHB1ENR |= 1u << port;
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2 * pin))) | (GPIO_MODE_AF << (2 * pin));
    volatile uint32_t *afr = pin < 8 ? &GPIO_AFRL(port) : &GPIO_AFRH(port);
    unsigned shift = 4 * (pin % 8);
    *afr = (*afr & ~(0xFu << shift)) | (af << shift);
}

void motors_init(void)
{
    RCC_APB1ENR |= (1u << 0) | (1u << 1); /* TIM2, TIM3 */
    for (int i = 0; i < 4; i++) {
        uint32_t t = timer[i];
        unsigned ch = channel[i];
        volatile uint32_t *ccmr = ch <= 2 ? &TIM_CCMR1(t) : &TIM_CCMR2(t);
        unsigned shift = ch % 2 ? 0u : 8u;
        *ccmr = (*ccmr & ~(0xFFu << shift)) | ((TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << shift);
        TIM_CCR(t, ch) = PWM_MIN_US;
        TIM_CCER(t) |= TIM_CCER_E(ch);
    }
    for (int k = 0; k < 2; k++) {
        uint32_t t = k ? TIM3_BASE : TIM2_BASE;
        TIM_PSC(t) = PWM_PSC;
        TIM_ARR(t) = PWM_ARR;
        TIM_CR1(t) = TIM_CR1_ARPE;
        TIM_EGR(t) = TIM_EGR_UG; /* PSC, ARR and the CCRs in force before the first period */
        TIM_CR1(t) = TIM_CR1_ARPE | TIM_CR1_CEN;
    }
    pin_af(PORT_B, 0, 2); /* S1 TIM3_CH3 */
    pin_af(PORT_B, 1, 2); /* S2 TIM3_CH4 */
    pin_af(PORT_A, 3, 1); /* S3 TIM2_CH4 */
    pin_af(PORT_A, 2, 1); /* S4 TIM2_CH3 */
}

void motors_write_us(uint8_t motor, uint16_t us)
{
    if (motor > 3)
        return;
    if (us < PWM_MIN_US)
        us = PWM_MIN_US;
    if (us > PWM_MAX_US)
        us = PWM_MAX_US;
    TIM_CCR(timer[motor], channel[motor]) = us;
}

void motors_off(void)
{
    TIM_CCER(TIM2_BASE) = 0;
    TIM_CCER(TIM3_BASE) = 0;
}
