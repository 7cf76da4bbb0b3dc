/* A PWM receiver channel on a pin change interrupt, the way Mega flight controllers read RC: port K bit 3
 * (PCINT19) on the ATmega2560, port D bit 3 (PCINT19) on the ATmega328P, both PCINT2_vect. Each high
 * pulse's width in microseconds (Timer1 at 2 MHz) goes out on USART0 as two bytes, little-endian. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#if defined(__AVR_ATmega2560__)
#define RC_PIN PINK
#else
#define RC_PIN PIND
#endif

static volatile uint16_t rise, width;
static volatile uint8_t fresh;

ISR(PCINT2_vect)
{
    static uint8_t last;
    uint16_t now = TCNT1;
    uint8_t level = RC_PIN & _BV(3);
    if (level == last)
        return;
    last = level;
    if (level) {
        rise = now;
    } else {
        width = (uint16_t)(now - rise) / 2;
        fresh = 1;
    }
}

int main(void)
{
    UBRR0 = 3; /* 500000 baud with U2X */
    UCSR0A = _BV(U2X0);
    UCSR0B = _BV(TXEN0);
    TCCR1B = _BV(CS11);
    PCMSK2 = _BV(3);
    PCICR = _BV(PCIE2);
    sei();
    for (;;) {
        if (fresh) {
            cli();
            uint16_t w = width;
            fresh = 0;
            sei();
            while (!(UCSR0A & _BV(UDRE0))) {
            }
            UDR0 = w & 0xFF;
            while (!(UCSR0A & _BV(UDRE0))) {
            }
            UDR0 = w >> 8;
        }
    }
}
