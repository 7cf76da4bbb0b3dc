/* A busy loop and nothing else: the engine's speed (bench/mcu_rates.py) and a firmware that hangs (no
 * TWI, no pulses). */
#include <stdint.h>

volatile uint32_t counter;

int main(void)
{
    for (;;)
        counter++;
}
