/* Start-up of the reference FC on the STM32F405: the FPU on (CPACR, before any float instruction),
   .data copied from flash, .bss cleared, then main. A fault or an unexpected interrupt spins in
   fault_handler with interrupts off: the rig names it with pc and the fault registers (docs/mcu.md). */
#include <stdint.h>

#include "stm32f405.h"

extern uint32_t __stack, __data_start, __data_end, __data_load, __bss_start, __bss_end;
int main(void);
void reset_handler(void);
void fault_handler(void);
void systick_handler(void);
void usart1_handler(void);
/* the telemetry's USART (USART2 on the Black Pill, USART6 on the F405 board): the one in use is defined */
void usart2_handler(void) __attribute__((weak, alias("fault_handler")));
void usart6_handler(void) __attribute__((weak, alias("fault_handler")));
void dma1_stream6_handler(void) __attribute__((weak, alias("fault_handler")));
void dma2_stream6_handler(void) __attribute__((weak, alias("fault_handler")));

void reset_handler(void)
{
    SCB_CPACR |= 0xFu << 20; /* CP10 and CP11: full access */
    __asm volatile("dsb\n isb");
    for (uint32_t *src = &__data_load, *dst = &__data_start; dst < &__data_end;)
        *dst++ = *src++;
    for (uint32_t *dst = &__bss_start; dst < &__bss_end;)
        *dst++ = 0;
    main();
    for (;;)
        __asm volatile("wfi");
}

void fault_handler(void)
{
    __asm volatile("cpsid i");
    for (;;)
        ;
}

#define F fault_handler
// clang-format off
/* the core's 16 exceptions, then the STM32F405's interrupts up to USART6 (IRQ 71, RM0090 table 61) */
__attribute__((section(".isr_vector"), used)) static void (*const vectors[16 + 72])(void) = {
    (void (*)(void))(uintptr_t)&__stack,
    reset_handler,
    F, F, F, F, F, /* NMI, HardFault, MemManage, BusFault, UsageFault */
    0, 0, 0, 0,
    F, F, 0, F, /* SVCall, DebugMonitor, -, PendSV */
    systick_handler,
    F, F, F, F, F, F, F, F, F, F, F, F, F, F, F, F, /* IRQ 0-15 */
    F,                                              /* IRQ 16 */
    dma1_stream6_handler,                           /* IRQ 17 */
    F, F, F, F, F, F, F, F, F, F, F, F, F, F,       /* IRQ 18-31 */
    F, F, F, F, F,                                  /* IRQ 32-36 */
    usart1_handler,                                 /* IRQ 37 */
    usart2_handler,                                 /* IRQ 38 */
    F, F, F, F, F, F, F, F, F, F, F, F, F, F, F, F, /* IRQ 39-54 */
    F, F, F, F, F, F, F, F, F, F, F, F, F, F,       /* IRQ 55-68 */
    dma2_stream6_handler,                           /* IRQ 69 */
    F,                                              /* IRQ 70 */
    usart6_handler,                                 /* IRQ 71 */
};
// clang-format on
