/* A parallel PWM receiver as STM32 flight controllers decode one (Betaflight's PWM input): a pulse per
   channel on its own pin, each pin a timer channel in input capture, timed from its rising edge to its
   falling edge by turning the channel's polarity (CCxP) at each capture. Eight channels on four timers
   none of the board's motors, I2C1 or USARTs use, each pin pulled down (a receiver's output idles low):
     1 PA8 TIM1_CH1 (AF1)   2 PA11 TIM1_CH4 (AF1)   3 PA6 TIM3_CH1 (AF2)   4 PA7 TIM3_CH2 (AF2)
     5 PA0 TIM5_CH1 (AF2)   6 PA1 TIM5_CH2 (AF2)    7 PC8 TIM8_CH3 (AF3)   8 PC9 TIM8_CH4 (AF3)
   The timers count at 1 MHz (the reset clock's 16 MHz HSI on both APBs, PSC 15: RM0090 17.3.1,
   CK_CNT = f_CK_PSC / (PSC + 1)) over 16 bits, so a width is the two captures' difference modulo 2^16 in
   microseconds. The falling edge of channel 8 ends a frame (the receiver puts the channels out one after
   another). The first REPORTED frames go out through semihosting as "pwm_F_C=0xWIDTH" lines
   (tests/stm32/test_pwm_rx.py); every frame goes out on USART6 TX as a text line "PWM w1 ... w8". */
#include "semihost.h"
#include "stm32f405.h"
#include "text_out.h"

#define CHANNELS 8u
#define REPORTED 3u
#define PULL_DOWN 2u
#define TIM3_IRQ 29u
#define TIM5_IRQ 50u
#define TIM8_CC_IRQ 46u

static const struct {
    uint32_t timer, port;
    unsigned pin, channel, af;
} inputs[CHANNELS] = {
    { TIM1_BASE, PORT_A, 8, 1, 1 }, { TIM1_BASE, PORT_A, 11, 4, 1 }, { TIM3_BASE, PORT_A, 6, 1, 2 },
    { TIM3_BASE, PORT_A, 7, 2, 2 }, { TIM5_BASE, PORT_A, 0, 1, 2 },  { TIM5_BASE, PORT_A, 1, 2, 2 },
    { TIM8_BASE, PORT_C, 8, 3, 3 }, { TIM8_BASE, PORT_C, 9, 4, 3 },
};

static volatile uint32_t widths[2][CHANNELS], frames; /* (the frame being filled: frames % 2) */
static uint32_t rise[CHANNELS];

/* The captures waiting on @timer: a rising edge keeps its time and waits for the falling one, a falling
   edge gives the width */
static void captures(uint32_t timer)
{
    for (unsigned k = 0; k < CHANNELS; k++) {
        unsigned ch = inputs[k].channel;
        if (inputs[k].timer != timer || !(TIM_SR(timer) & TIM_SR_CCIF(ch))) {
            continue;
        }
        uint32_t at = TIM_CCR(timer, ch); /* the read clears CCxIF (RM0090 17.4.5) */
        if (!(TIM_CCER(timer) & TIM_CCER_P(ch))) {
            rise[k] = at;
            TIM_CCER(timer) |= TIM_CCER_P(ch);
            continue;
        }
        TIM_CCER(timer) &= ~TIM_CCER_P(ch);
        widths[frames % 2][k] = (at - rise[k]) & 0xFFFFu;
        if (k == CHANNELS - 1u) {
            frames++;
        }
    }
}

void tim1_cc_handler(void) { captures(TIM1_BASE); }
void tim3_handler(void) { captures(TIM3_BASE); }
void tim5_handler(void) { captures(TIM5_BASE); }
void tim8_cc_handler(void) { captures(TIM8_BASE); }

static void input_init(unsigned k)
{
    uint32_t t = inputs[k].timer, port = inputs[k].port;
    unsigned pin = inputs[k].pin, ch = inputs[k].channel;
    RCC_AHB1ENR |= 1u << port;
    GPIO_PUPDR(port) = (GPIO_PUPDR(port) & ~(3u << (2u * pin))) | PULL_DOWN << (2u * pin);
    volatile uint32_t *afr = pin < 8u ? &GPIO_AFRL(port) : &GPIO_AFRH(port);
    *afr = (*afr & ~(0xFu << (4u * (pin % 8u)))) | inputs[k].af << (4u * (pin % 8u));
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2u * pin))) | GPIO_MODE_AF << (2u * pin);
    volatile uint32_t *ccmr = ch <= 2u ? &TIM_CCMR1(t) : &TIM_CCMR2(t);
    *ccmr |= TIM_CCMR_IC_TI_OWN << (ch % 2u ? 0u : 8u);
    TIM_CCER(t) |= TIM_CCER_E(ch); /* rising edges first */
    TIM_DIER(t) |= TIM_DIER_CCIE(ch);
}

int main(void)
{
    RCC_APB2ENR |= (1u << 0) | (1u << 1) | RCC_APB2ENR_USART6EN; /* TIM1, TIM8 */
    RCC_APB1ENR |= (1u << 1) | (1u << 3);                        /* TIM3, TIM5 */
    USART_CR1(USART6_BASE) = USART_CR1_UE | USART_CR1_TE;
    for (unsigned k = 0; k < CHANNELS; k++) {
        input_init(k);
    }
    static const uint32_t timers[4] = { TIM1_BASE, TIM3_BASE, TIM5_BASE, TIM8_BASE };
    for (unsigned i = 0; i < 4u; i++) {
        TIM_PSC(timers[i]) = 15u;
        TIM_ARR(timers[i]) = 0xFFFFu;
        TIM_EGR(timers[i]) = TIM_EGR_UG;
        TIM_SR(timers[i]) = 0;
        TIM_CR1(timers[i]) = TIM_CR1_CEN;
    }
    NVIC_ISER(0) = 1u << TIM1_CC_IRQ | 1u << TIM3_IRQ;
    NVIC_ISER(1) = 1u << (TIM8_CC_IRQ - 32u) | 1u << (TIM5_IRQ - 32u);
    for (unsigned sent = 0;;) {
        __asm volatile("cpsid i"); /* (an interrupt between the test and WFI still wakes it) */
        if (sent == frames) {
            __asm volatile("wfi");
        }
        __asm volatile("cpsie i");
        if (sent == frames) {
            continue;
        }
        uint32_t w[CHANNELS];
        __asm volatile("cpsid i"); /* (a copy the next frame's captures cannot tear) */
        for (unsigned c = 0; c < CHANNELS; c++) {
            w[c] = widths[sent % 2][c];
        }
        __asm volatile("cpsie i");
        if (sent < REPORTED) {
            report_widths("pwm", sent, w, CHANNELS);
        }
        send_widths("PWM", w, CHANNELS);
        sent++;
    }
}
