/* Start-up of the STM32 tier's test firmwares on the STM32F405: .data copied from flash, .bss cleared,
   then main; a fault or an interrupt nobody handles reports its name and the fault status registers through semihosting and
   ends the run with status 3, so QEMU always exits. */
#include "semihost.h"
#include <stdint.h>

extern uint32_t __stack, __data_start, __data_end, __data_load, __bss_start, __bss_end;
int main(void);
void reset_handler(void);
void fault_handler(void);
/* SysTick, the WWDG's and the FLASH's interrupts (NVIC lines 0 and 4), I2C1's event and error interrupts
   (31 and 32), the timers' (24-30, 43-46, 50, 54, 55) and the DMA streams' the tests use: a firmware that
   enables them defines these */
void i2c1_ev_handler(void) __attribute__((weak, alias("fault_handler")));
void i2c1_er_handler(void) __attribute__((weak, alias("fault_handler")));
void systick_handler(void) __attribute__((weak, alias("fault_handler")));
void wwdg_handler(void) __attribute__((weak, alias("fault_handler")));
void flash_handler(void) __attribute__((weak, alias("fault_handler")));
void tim1_brk_tim9_handler(void) __attribute__((weak, alias("fault_handler")));
void tim1_up_tim10_handler(void) __attribute__((weak, alias("fault_handler")));
void tim1_trg_com_tim11_handler(void) __attribute__((weak, alias("fault_handler")));
void tim1_cc_handler(void) __attribute__((weak, alias("fault_handler")));
void tim2_handler(void) __attribute__((weak, alias("fault_handler")));
void tim3_handler(void) __attribute__((weak, alias("fault_handler")));
void tim4_handler(void) __attribute__((weak, alias("fault_handler")));
void tim8_brk_tim12_handler(void) __attribute__((weak, alias("fault_handler")));
void tim8_up_tim13_handler(void) __attribute__((weak, alias("fault_handler")));
void tim8_trg_com_tim14_handler(void) __attribute__((weak, alias("fault_handler")));
void tim8_cc_handler(void) __attribute__((weak, alias("fault_handler")));
void tim5_handler(void) __attribute__((weak, alias("fault_handler")));
void tim6_dac_handler(void) __attribute__((weak, alias("fault_handler")));
void tim7_handler(void) __attribute__((weak, alias("fault_handler")));
/* USART1 (NVIC line 37): usart.c */
void usart1_handler(void) __attribute__((weak, alias("fault_handler")));
/* the BusFault (exception 5): a firmware that probes absent memory (f411_map.c) defines it */
void bus_fault_handler(void) __attribute__((weak, alias("fault_handler")));
/* the DMA streams' interrupts: DMA1 stream 0-6 on 11-17 and stream 7 on 47, DMA2 stream 0-4 on 56-60 and
   stream 5-7 on 68-70 */
void exti0_handler(void) __attribute__((weak, alias("fault_handler")));
void exti1_handler(void) __attribute__((weak, alias("fault_handler")));
void exti2_handler(void) __attribute__((weak, alias("fault_handler")));
void exti9_5_handler(void) __attribute__((weak, alias("fault_handler")));
void exti15_10_handler(void) __attribute__((weak, alias("fault_handler")));
void dma1_stream0_handler(void) __attribute__((weak, alias("fault_handler")));
void dma1_stream2_handler(void) __attribute__((weak, alias("fault_handler")));
void dma1_stream6_handler(void) __attribute__((weak, alias("fault_handler")));
void dma2_stream0_handler(void) __attribute__((weak, alias("fault_handler")));
void adc_handler(void) __attribute__((weak, alias("fault_handler")));
void dma2_stream5_handler(void) __attribute__((weak, alias("fault_handler")));
void dma2_stream6_handler(void) __attribute__((weak, alias("fault_handler")));
void usart6_handler(void) __attribute__((weak, alias("fault_handler")));

#define CFSR (*(volatile uint32_t *)0xE000ED28u)
#define HFSR (*(volatile uint32_t *)0xE000ED2Cu)

void reset_handler(void)
{
    for (uint32_t *src = &__data_load, *dst = &__data_start; dst < &__data_end;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = &__bss_start; dst < &__bss_end;) {
        *dst++ = 0;
    }
    exit_with((uint32_t)main());
}

void fault_handler(void)
{
    report("fault_cfsr", CFSR);
    report("fault_hfsr", HFSR);
    exit_with(3);
}

#define F fault_handler
// clang-format off
/* the core's 16 exceptions, then the STM32F405's interrupts up to USART6 (RM0090 table 61) */
__attribute__((section(".isr_vector"), used)) static void (*const vectors[16 + 72])(void) = {
    (void (*)(void))(uintptr_t)&__stack,
    reset_handler,
    fault_handler,
    fault_handler,
    fault_handler,
    bus_fault_handler,
    fault_handler,
    0,
    0,
    0,
    0,
    fault_handler,
    fault_handler,
    0,
    fault_handler,
    systick_handler,
    wwdg_handler, /* IRQ 0 */
    F, F, F,      /* IRQ 1-3 */
    flash_handler, /* IRQ 4 */
    F,            /* IRQ 5 */
    exti0_handler, /* IRQ 6 */
    exti1_handler, /* IRQ 7 */
    exti2_handler, /* IRQ 8 */
    F, F,          /* IRQ 9-10: EXTI3, EXTI4 */
    dma1_stream0_handler, /* IRQ 11 */
    F,                    /* IRQ 12: DMA1 stream 1 */
    dma1_stream2_handler, /* IRQ 13 */
    F, F, F,              /* IRQ 14-16: DMA1 stream 3-5 */
    dma1_stream6_handler, /* IRQ 17 */
    adc_handler,  /* IRQ 18 */
    F, F, F, F,                                     /* IRQ 19-22 */
    exti9_5_handler, /* IRQ 23 */
    tim1_brk_tim9_handler, /* IRQ 24 */
    tim1_up_tim10_handler, /* IRQ 25 */
    tim1_trg_com_tim11_handler, /* IRQ 26 */
    tim1_cc_handler, /* IRQ 27 */
    tim2_handler, /* IRQ 28 */
    tim3_handler, /* IRQ 29 */
    tim4_handler, /* IRQ 30 */
    i2c1_ev_handler, /* IRQ 31 */
    i2c1_er_handler, /* IRQ 32 */
    F, F, F, F,                                     /* IRQ 33-36 */
    usart1_handler, /* IRQ 37 */
    F, F,           /* IRQ 38-39 */
    exti15_10_handler, /* IRQ 40 */
    F, F,              /* IRQ 41-42 */
    tim8_brk_tim12_handler, /* IRQ 43 */
    tim8_up_tim13_handler, /* IRQ 44 */
    tim8_trg_com_tim14_handler, /* IRQ 45 */
    tim8_cc_handler, /* IRQ 46 */
    F, F, F,                                        /* IRQ 47-49 */
    tim5_handler, /* IRQ 50 */
    F, F, F,                                        /* IRQ 51-53 */
    tim6_dac_handler, /* IRQ 54 */
    tim7_handler, /* IRQ 55 */
    dma2_stream0_handler, /* IRQ 56 */
    F, F, F, F, F, F, F, F, F, F, F,                /* IRQ 57-67: DMA2 stream 1-4, ... */
    dma2_stream5_handler, /* IRQ 68 */
    dma2_stream6_handler, /* IRQ 69 */
    F,                    /* IRQ 70: DMA2 stream 7 */
    usart6_handler,       /* IRQ 71 */
};
// clang-format on
