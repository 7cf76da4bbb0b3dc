/* Enables the watchdog (15 ms) and never resets it: the MCU resets over and over. */
#include <avr/wdt.h>

volatile unsigned long counter;

int main(void)
{
    wdt_enable(WDTO_15MS);
    for (;;)
        counter++;
}
