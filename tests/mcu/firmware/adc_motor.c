/* A battery monitor while a motor runs: motor 1's ESC output pulses 1000 us (zero throttle) for the first
 * 25 readings, then 2000 us (full throttle); ADC0 (PC0 on the 328P, PF0 on the 2560) is read against AVCC
 * every 10 ms or so and sent as a line, "# adc 640", on USART0 at 115200 8N1 (adc_batt.c's).
 * Motor 1 as pulse_stop.c has it: ATmega2560 Timer3 OC3B (PE4, the Mega's D2), ATmega328P Timer1 OC1A
 * (PB1, the Pro Mini's D9); phase-correct PWM, TOP = ICR = 2040 at a 0.5 us tick: OCR us wide pulses. */
#include "uart0_115200.h"
#include <avr/io.h>
#include <stdint.h>
#include <util/delay.h>

#if defined(__AVR_ATmega2560__)
#define OCR_MOTOR OCR3B
#else
#define OCR_MOTOR OCR1A
#endif

static void send_reading(uint16_t v)
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

int main(void)
{
    uart0_init(_BV(TXEN0));
#if defined(__AVR_ATmega2560__)
    DDRE |= _BV(4);
    ICR3 = 2040;
    OCR3B = 1000;
    TCCR3A = _BV(COM3B1) | _BV(WGM31);
    TCCR3B = _BV(WGM33) | _BV(CS31);
#else
    DDRB |= _BV(1);
    ICR1 = 2040;
    OCR1A = 1000;
    TCCR1A = _BV(COM1A1) | _BV(WGM11);
    TCCR1B = _BV(WGM13) | _BV(CS11);
#endif
    ADMUX = _BV(REFS0); /* AVCC, ADC0 */
    ADCSRA = _BV(ADEN) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
    for (uint8_t n = 0;; n++) {
        if (n == 25)
            OCR_MOTOR = 2000;
        ADCSRA |= _BV(ADSC);
        while (ADCSRA & _BV(ADSC)) {
        }
        send_reading(ADC);
        _delay_ms(10);
    }
}
