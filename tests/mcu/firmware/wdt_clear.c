/* Turns the watchdog off the way avr-libc does (wdt_disable), then loops without resetting it: with the
 * WDTON fuse the watchdog stays on and resets the MCU every 16 ms; without it, the loop runs on. */
#include <avr/wdt.h>

volatile unsigned long counter;

int main(void)
{
    wdt_disable();
    for (;;)
        counter++;
}
