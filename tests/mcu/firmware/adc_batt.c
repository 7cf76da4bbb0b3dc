/* A battery monitor as voltage-compensating FCs have one: reads ADC0 (PC0 on the 328P, PF0 on the 2560)
 * against AVCC every 10 ms and sends the 10-bit result as a line, "# adc 640", on USART0 at 115200 8N1. */
#include "adc_line.h"
#include <util/delay.h>

int main(void)
{
    uart0_init(_BV(TXEN0));
    adc0_init();
    for (;;) {
        send_reading(adc0_read());
        _delay_ms(10);
    }
}
