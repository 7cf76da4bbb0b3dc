/* A battery monitor as voltage-compensating FCs have one: reads ADC0 (PC0 on the 328P, PF0 on the 2560)
 * against AVCC every 10 ms and sends the 10-bit result as a line, "# adc 640", on USART0 at 115200 8N1. */
#include "uart0_115200.h"
#include <avr/io.h>
#include <stdint.h>
#include <util/delay.h>

int main(void)
{
    uart0_init(_BV(TXEN0));
    ADMUX = _BV(REFS0); /* AVCC, ADC0 */
    ADCSRA = _BV(ADEN) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
    for (;;) {
        ADCSRA |= _BV(ADSC);
        while (ADCSRA & _BV(ADSC)) {
        }
        uint16_t v = ADC;
        char text[12] = "# adc ";
        uint8_t n = 6;
        char digits[5];
        uint8_t k = 0;
        do {
            digits[k++] = (char)('0' + v % 10);
            v /= 10;
        } while (v);
        while (k)
            text[n++] = digits[--k];
        for (uint8_t i = 0; i < n; i++)
            put((uint8_t)text[i]);
        put('\r');
        put('\n');
        _delay_ms(10);
    }
}
