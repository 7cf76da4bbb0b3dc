/* The motor outputs (motors.h): PWM mode 1 with CCR preloaded (OCxPE) and ARR preloaded (ARPE), so a
   new pulse takes effect at the next update event and never makes a runt pulse (RM0090 18.3.9). */
#include "motors.h"

#include "board.h"
#include "stm32f405.h"

/* motor i on its timer's channel, at its pin (board.h) */
static const board_motor motor[4] = BOARD_MOTORS;

/* whether motor @i's timer is that of a motor before it (set up once) */
static int timer_seen(int i)
{
    for (int k = 0; k < i; k++)
        if (motor[k].timer == motor[i].timer)
            return 1;
    return 0;
}

void motors_init(void)
{
    RCC_APB1ENR |= BOARD_MOTOR_APB1ENR;
    for (int i = 0; i < 4; i++) {
        uint32_t t = motor[i].timer;
        unsigned ch = motor[i].channel;
        volatile uint32_t *ccmr = ch <= 2 ? &TIM_CCMR1(t) : &TIM_CCMR2(t);
        unsigned shift = ch % 2 ? 0u : 8u;
        *ccmr = (*ccmr & ~(0xFFu << shift)) | ((TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << shift);
        TIM_CCR(t, ch) = PWM_MIN_US;
        TIM_CCER(t) |= TIM_CCER_E(ch);
    }
    for (int i = 0; i < 4; i++) {
        if (timer_seen(i))
            continue;
        uint32_t t = motor[i].timer;
        TIM_PSC(t) = PWM_PSC;
        TIM_ARR(t) = PWM_ARR;
        TIM_CR1(t) = TIM_CR1_ARPE;
        TIM_EGR(t) = TIM_EGR_UG; /* PSC, ARR and the CCRs in force before the first period */
        TIM_CR1(t) = TIM_CR1_ARPE | TIM_CR1_CEN;
    }
    for (int i = 0; i < 4; i++)
        board_pin_af(motor[i].port, motor[i].pin, motor[i].af);
}

void motors_write_us(uint8_t m, uint16_t us)
{
    if (m > 3)
        return;
    if (us < PWM_MIN_US)
        us = PWM_MIN_US;
    if (us > PWM_MAX_US)
        us = PWM_MAX_US;
    TIM_CCR(motor[m].timer, motor[m].channel) = us;
}

void motors_off(void)
{
    for (int i = 0; i < 4; i++)
        TIM_CCER(motor[i].timer) = 0;
}
