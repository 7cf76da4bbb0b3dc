/* A PPM receiver as flight controllers decode one: the sum signal on PA0 (pulled up, AF1: TIM2_CH1),
   TIM2 at 1 MHz (the reset clock's 16 MHz HSI, PSC 15) capturing its falling edges in the CC1
   interrupt, the core asleep in WFI between. A gap longer than SYNC_US is the frame's sync; the 8
   intervals after it are the channels' widths in microseconds. The rig drives the pin
   (tests/stm32/test_ppm.py: the engine's pin_drive over the link); the firmware reports FRAMES frames
   through semihosting as "ppm_F_C=0xWIDTH" lines and the sync gap before each as "ppm_F_sync", then
   sleeps. */
#include "semihost.h"
#include "stm32f405.h"

#define CHANNELS 8u
#define FRAMES 3u
#define SYNC_US 2700u /* longer than any channel (2100 us at most), shorter than a frame's gap */
#define TIM2_IRQ 28u
#define PULL_UP 1u

static volatile uint32_t widths[FRAMES][CHANNELS], syncs[FRAMES], frames;
static uint32_t last, channel = CHANNELS, captures;

void tim2_handler(void)
{
    uint32_t at = TIM_CCR(TIM2_BASE, 1); /* the read clears CC1IF (RM0090 18.4.5) */
    uint32_t delta = at - last;
    last = at;
    if (captures++ == 0 || delta > SYNC_US) {
        if (frames < FRAMES) {
            syncs[frames] = captures == 1 ? 0 : delta;
        }
        channel = 0;
        return;
    }
    if (channel < CHANNELS && frames < FRAMES) {
        widths[frames][channel++] = delta;
        if (channel == CHANNELS) {
            frames++;
        }
    }
}

int main(void)
{
    RCC_AHB1ENR |= 1u << PORT_A;
    RCC_APB1ENR |= 1u; /* TIM2EN */
    GPIO_PUPDR(PORT_A) = (GPIO_PUPDR(PORT_A) & ~3u) | PULL_UP;
    GPIO_AFRL(PORT_A) = (GPIO_AFRL(PORT_A) & ~0xFu) | 1u;
    GPIO_MODER(PORT_A) = (GPIO_MODER(PORT_A) & ~3u) | GPIO_MODE_AF;
    TIM_PSC(TIM2_BASE) = 15u;
    TIM_ARR(TIM2_BASE) = 0xFFFFFFFFu;
    TIM_CCMR1(TIM2_BASE) = TIM_CCMR_IC_TI_OWN;
    TIM_CCER(TIM2_BASE) = TIM_CCER_E(1) | TIM_CCER_P(1); /* falling edges */
    TIM_DIER(TIM2_BASE) = TIM_DIER_CCIE(1);
    TIM_EGR(TIM2_BASE) = TIM_EGR_UG;
    TIM_SR(TIM2_BASE) = 0;
    NVIC_ISER(0) = 1u << TIM2_IRQ;
    TIM_CR1(TIM2_BASE) = TIM_CR1_CEN;
    while (frames < FRAMES) {
        __asm volatile("wfi");
    }
    for (unsigned f = 0; f < FRAMES; f++) {
        char sync[] = "ppm_0_sync";
        sync[4] = (char)('0' + f);
        report(sync, syncs[f]);
        for (unsigned c = 0; c < CHANNELS; c++) {
            char name[] = "ppm_0_0";
            name[4] = (char)('0' + f);
            name[6] = (char)('1' + c);
            report(name, widths[f][c]);
        }
    }
    for (;;) {
        __asm volatile("wfi");
    }
}
