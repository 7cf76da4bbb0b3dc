/* A PPM receiver as flight controllers decode one: the sum signal on PA0 (pulled up, AF1: TIM2_CH1),
   TIM2 at 1 MHz (the reset clock's 16 MHz HSI, PSC 15) capturing its falling edges in the CC1
   interrupt, the core asleep in WFI between. A gap longer than SYNC_US is the frame's sync; the 8
   intervals after it are the channels' widths in microseconds. The rig drives the pin (the engine's
   pin_drive over the link). The first REPORTED frames go out through semihosting as "ppm_F_C=0xWIDTH"
   lines with the sync gap before each as "ppm_F_sync" (tests/stm32/test_ppm.py); every frame goes out
   on USART6 TX (the STM32F405 board's telemetry port) as a text line "PPM w1 ... w8" in decimal, which
   the MCU session logs as telemetry. */
#include "semihost.h"
#include "stm32f405.h"
#include "text_out.h"

#define CHANNELS 8u
#define REPORTED 3u
#define SYNC_US 2700u /* longer than any channel (2100 us at most), shorter than a frame's gap */
#define TIM2_IRQ 28u
#define PULL_UP 1u

static volatile uint32_t widths[2][CHANNELS], syncs[2], frames; /* (the frame being filled: frames % 2) */
static uint32_t last, channel = CHANNELS, captures, sync;

void tim2_handler(void)
{
    uint32_t at = TIM_CCR(TIM2_BASE, 1); /* the read clears CC1IF (RM0090 18.4.5) */
    uint32_t delta = at - last;
    last = at;
    if (captures++ == 0 || delta > SYNC_US) {
        sync = captures == 1 ? 0 : delta;
        channel = 0;
        return;
    }
    if (channel < CHANNELS) {
        widths[frames % 2][channel++] = delta;
        if (channel == CHANNELS) {
            syncs[frames % 2] = sync;
            frames++;
        }
    }
}

static void send_frame(unsigned f)
{
    uint32_t w[CHANNELS];
    __asm volatile("cpsid i"); /* (a copy the next frame's captures cannot tear) */
    for (unsigned c = 0; c < CHANNELS; c++) {
        w[c] = widths[f % 2][c];
    }
    uint32_t gap = syncs[f % 2];
    __asm volatile("cpsie i");
    if (f < REPORTED) {
        char name[] = "ppm_0_sync";
        name[4] = (char)('0' + f);
        report(name, gap);
        report_widths("ppm", f, w, CHANNELS);
    }
    send_widths("PPM", w, CHANNELS);
}

int main(void)
{
    RCC_AHB1ENR |= 1u << PORT_A;
    RCC_APB1ENR |= 1u; /* TIM2EN */
    RCC_APB2ENR |= RCC_APB2ENR_USART6EN;
    USART_CR1(USART6_BASE) = USART_CR1_UE | USART_CR1_TE;
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
    for (unsigned sent = 0;;) {
        while (sent == frames) {
            __asm volatile("wfi");
        }
        send_frame(sent++);
    }
}
