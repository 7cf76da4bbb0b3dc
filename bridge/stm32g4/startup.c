/* Start-up of the bridge firmware on the STM32G431 (bare metal): the vector table at the start of
   flash (RM0440 §14: 16 Cortex-M4 exceptions, then the STM32G4's 102 interrupts), the reset handler
   (FPU on, .data copied from flash, .bss cleared, then main) and a default handler for everything
   else. A fault spins until the watchdog resets the MCU (the reset cause is then IWDG, which STATUS
   can tell the host). */
#include <stdint.h>

#include "regs.h"

extern uint32_t __data_start, __data_end, __data_load, __bss_start, __bss_end, __stack_top;
int main(void);
void reset_handler(void);
void default_handler(void);

/* the handlers firmware.c defines; those it does not are the default handler */
#define WEAK_ALIAS __attribute__((weak, alias("default_handler")))
void tim2_irq(void) WEAK_ALIAS;
void i2c1_ev_irq(void) WEAK_ALIAS;
void i2c1_er_irq(void) WEAK_ALIAS;
void i2c3_ev_irq(void) WEAK_ALIAS;
void i2c3_er_irq(void) WEAK_ALIAS;
void usart1_irq(void) WEAK_ALIAS;
void dma1_ch2_irq(void) WEAK_ALIAS;

void reset_handler(void)
{
    SCB_VTOR = FLASH_BASE;   /* our table, also when a bootloader jumped here (stm32flash -g) */
    SCB_CPACR |= 0xFu << 20; /* CP10, CP11: the FPU (the code is built for the hard-float ABI) */
    __asm volatile("dsb\n isb" ::: "memory");
    const uint32_t *src = &__data_load;
    for (uint32_t *p = &__data_start; p < &__data_end;)
        *p++ = *src++;
    for (uint32_t *p = &__bss_start; p < &__bss_end;)
        *p++ = 0;
    main();
    for (;;) {
    }
}

void default_handler(void)
{
    for (;;) {
    }
}

typedef void (*vector)(void);

__attribute__((section(".isr_vector"), used)) static const vector vectors[16 + IRQ_COUNT] = {
    [0] = (vector)(uintptr_t)&__stack_top,
    [1] = reset_handler,
    [2] = default_handler,  /* NMI */
    [3] = default_handler,  /* HardFault */
    [4] = default_handler,  /* MemManage */
    [5] = default_handler,  /* BusFault */
    [6] = default_handler,  /* UsageFault */
    [11] = default_handler, /* SVCall */
    [12] = default_handler, /* DebugMonitor */
    [14] = default_handler, /* PendSV */
    [15] = default_handler, /* SysTick */
    [16 + IRQ_DMA1_CH2] = dma1_ch2_irq,
    [16 + IRQ_TIM2] = tim2_irq,
    [16 + IRQ_I2C1_EV] = i2c1_ev_irq,
    [16 + IRQ_I2C1_ER] = i2c1_er_irq,
    [16 + IRQ_USART1] = usart1_irq,
    [16 + IRQ_I2C3_EV] = i2c3_ev_irq,
    [16 + IRQ_I2C3_ER] = i2c3_er_irq,
};
