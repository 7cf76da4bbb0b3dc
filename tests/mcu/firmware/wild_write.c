/* Stores through a pointer far past the end of SRAM (a corrupted pointer): simavr's core stops on it; the
 * rig must live on. */
#include <stdint.h>

volatile uint16_t where = 0xFFF0;

int main(void)
{
    *(volatile uint8_t *)where = 0x55;
    for (;;) {
    }
}
