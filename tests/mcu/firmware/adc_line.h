/* What the battery-monitor firmwares share (adc_batt.c, adc_motor.c): ADC0 (PC0 on the 328P, PF0 on the
 * 2560) read against AVCC, and a reading sent as a line, "# adc 640", on USART0 (uart0_115200.h). */
#ifndef ADC_LINE_H
#define ADC_LINE_H

#include "uart0_115200.h"
#include <avr/io.h>
#include <stdint.h>

static inline void adc0_init(void)
{
    ADMUX = _BV(REFS0); /* AVCC, ADC0 */
    ADCSRA = _BV(ADEN) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
}

/* One conversion, waited for: the 10-bit result */
static inline uint16_t adc0_read(void)
{
    ADCSRA |= _BV(ADSC);
    while (ADCSRA & _BV(ADSC)) {
    }
    return ADC;
}

static inline void send_reading(uint16_t v)
{
    char digits[5];
    uint8_t k = 0;
    do {
        digits[k++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    const char *head = "# adc ";
    while (*head)
        put((uint8_t)*head++);
    while (k)
        put((uint8_t)digits[--k]);
    put('\r');
    put('\n');
}

#endif
