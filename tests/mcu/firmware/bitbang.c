/* Two ESC outputs on two compare-output pins of one timer: the first driven by the timer (fast PWM, TOP
 * ICRn = 4999 at 2 MHz: a 2.5 ms period, OCR = 2199: 1.1 ms pulses), the second by plain PORT writes, its
 * compare output disconnected (COM = 0: "the pin functions as a normal port pin"), 1.5 ms high, 1 ms low.
 * ATmega2560: timer 3, OC3B (PE4) and OC3C (PE5); ATmega328P: timer 1, OC1A (PB1) and OC1B (PB2). */
#include <avr/io.h>
#include <util/delay.h>

#if defined(__AVR_ATmega2560__)
#define TCCRA TCCR3A
#define TCCRB TCCR3B
#define ICR ICR3
#define OCR OCR3B
#define COM_TIMED _BV(COM3B1)
#define WGM_A _BV(WGM31)
#define WGM_B (_BV(WGM33) | _BV(WGM32) | _BV(CS31))
#define DDR DDRE
#define PORT PORTE
#define TIMED _BV(PE4)
#define BANGED _BV(PE5)
#else
#define TCCRA TCCR1A
#define TCCRB TCCR1B
#define ICR ICR1
#define OCR OCR1A
#define COM_TIMED _BV(COM1A1)
#define WGM_A _BV(WGM11)
#define WGM_B (_BV(WGM13) | _BV(WGM12) | _BV(CS11))
#define DDR DDRB
#define PORT PORTB
#define TIMED _BV(PB1)
#define BANGED _BV(PB2)
#endif

int main(void)
{
    DDR |= TIMED | BANGED;
    ICR = 4999;
    OCR = 2199;
    TCCRA = COM_TIMED | WGM_A;
    TCCRB = WGM_B;
    for (;;) {
        PORT |= BANGED;
        _delay_us(1500);
        PORT &= (uint8_t)~BANGED;
        _delay_us(1000);
    }
}
