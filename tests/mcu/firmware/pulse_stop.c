/* An ESC output that stops: motor 1's pin pulses 1500 us at about 490 Hz for half a second, then its
 * compare output is disconnected and the firmware spins, as a firmware that crashed into a loop would.
 * ATmega2560: Timer3 OC3B (PE4, the Mega's D2); ATmega328P: Timer1 OC1A (PB1, the Pro Mini's D9). Both
 * phase-correct PWM, TOP = ICR = 2040 at a 0.5 us tick: a 2.04 ms period, OCR = 1500 gives 1500 us. */
#include <avr/io.h>
#include <util/delay.h>

int main(void)
{
#if defined(__AVR_ATmega2560__)
    DDRE |= _BV(4);
    ICR3 = 2040;
    OCR3B = 1500;
    TCCR3A = _BV(COM3B1) | _BV(WGM31);
    TCCR3B = _BV(WGM33) | _BV(CS31);
    _delay_ms(500);
    TCCR3A = _BV(WGM31); /* OC3B disconnected: no more pulses */
#else
    DDRB |= _BV(1);
    ICR1 = 2040;
    OCR1A = 1500;
    TCCR1A = _BV(COM1A1) | _BV(WGM11);
    TCCR1B = _BV(WGM13) | _BV(CS11);
    _delay_ms(500);
    TCCR1A = _BV(WGM11);
#endif
    for (;;) {
    }
}
