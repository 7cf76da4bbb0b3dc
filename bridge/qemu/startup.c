/* Start-up for the bridge core's tests on QEMU's mps2-an386 (Cortex-M4F), linked with newlib's rdimon
   (semihosting: stdio and files on the host, argv from -semihosting-config arg=..., exit status through
   SYS_EXIT_EXTENDED). The reset handler turns the FPU on (the code is built for the hard-float ABI) and
   hands over to newlib's _start, which clears .bss, sets up the heap and calls main. A fault of any kind
   ends the run with status 3 through semihosting, so QEMU always exits. Not a real board's start-up
   (that is bridge/stm32g4/startup.c). */
#include <stdint.h>

extern void _start(void);
extern uint32_t __stack;
void reset_handler(void);
void fault_handler(void);

#define CPACR (*(volatile uint32_t *)0xE000ED88u)

void reset_handler(void)
{
    CPACR |= 0xFu << 20; /* CP10, CP11: full access (the FPU) */
    __asm volatile("dsb\n isb" ::: "memory");
    _start();
    for (;;) {
    }
}

void fault_handler(void)
{
    /* SYS_EXIT (0x18) with ADP_Stopped_RunTimeErrorUnknown (0x20023): QEMU exits with status 1 */
    register uint32_t op __asm("r0") = 0x18;
    register uint32_t arg __asm("r1") = 0x20023;
    __asm volatile("bkpt 0xab" : : "r"(op), "r"(arg) : "memory");
    for (;;) {
    }
}

__attribute__((section(".vectors"), used)) static void (*const vectors[16])(void) = {
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
