/* Start-up of the STM32 tier's test firmwares on the STM32F405: .data copied from flash, .bss cleared,
   then main; a fault of any kind reports its name and the fault status registers through semihosting and
   ends the run with status 3, so QEMU always exits. */
#include "semihost.h"
#include <stdint.h>

extern uint32_t __stack, __data_start, __data_end, __data_load, __bss_start, __bss_end;
int main(void);
void reset_handler(void);
void fault_handler(void);

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

__attribute__((section(".isr_vector"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))(uintptr_t)&__stack,
    reset_handler,
    fault_handler,
    fault_handler,
    fault_handler,
    fault_handler,
    fault_handler,
    0,
    0,
    0,
    0,
    fault_handler,
    fault_handler,
    0,
    fault_handler,
    fault_handler,
};
