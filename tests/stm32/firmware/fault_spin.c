/* A firmware that faults and stays in its HardFault handler, as a production image does (no semihosting
   exit): its vector table is copied to RAM with a HardFault handler that spins, then an undefined
   instruction raises a UsageFault, which is disabled and so escalates to a HardFault (ARMv7-M B1.5.8).
   The STM32 tier's link must end the run naming the fault and its status registers. */
#include <stdint.h>

#define VTOR (*(volatile uint32_t *)0xE000ED08u)
#define VECTORS (16u + 56u)

void spin_handler(void);
/* (VTOR's alignment: the table's size rounded up to a power of two, 512 bytes for 72 vectors) */
static uint32_t ram_vectors[VECTORS] __attribute__((aligned(512)));

__attribute__((naked)) void spin_handler(void) { __asm volatile("b ."); }

int main(void)
{
    const uint32_t *flash_vectors = (const uint32_t *)0x08000000u;
    for (unsigned i = 0; i < VECTORS; i++) {
        ram_vectors[i] = flash_vectors[i];
    }
    ram_vectors[3] = (uint32_t)(uintptr_t)spin_handler; /* HardFault */
    VTOR = (uint32_t)(uintptr_t)ram_vectors;
    __asm volatile("dsb\n isb\n udf #0");
    return 0;
}
