/* Sleeps with interrupts off: nothing can ever wake it. */
#include <avr/interrupt.h>
#include <avr/sleep.h>

int main(void)
{
    cli();
    set_sleep_mode(SLEEP_MODE_PWR_DOWN);
    sleep_enable();
    sleep_cpu();
    for (;;) {
    }
}
