/* A parallel PWM receiver read as hobby FCs read one: four channels on pin change interrupts, PK0-PK3
 * (PCINT16-19) on the ATmega2560, PD4-PD7 (PCINT20-23) on the ATmega328P, both PCINT2_vect, each high
 * pulse timed by Timer1 at 2 MHz. When the fourth channel's pulse ends, the four widths in microseconds
 * go out on USART0 (115200 8N1) as 0xE3, 4, and each 16-bit little-endian. */
#include "uart0_115200.h"
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#if defined(__AVR_ATmega2560__)
#define RC_PIN PINK
#define RC_SHIFT 0
#define RC_MASK_REG PCMSK2
#else
#define RC_PIN PIND
#define RC_SHIFT 4
#define RC_MASK_REG PCMSK2
#endif

static volatile uint16_t rise[4], width[4];
static volatile uint8_t fresh;

ISR(PCINT2_vect)
{
    static uint8_t last;
    uint16_t now = TCNT1;
    uint8_t level = (uint8_t)(RC_PIN >> RC_SHIFT) & 0x0F;
    uint8_t changed = level ^ last;
    last = level;
    for (uint8_t ch = 0; ch < 4; ch++) {
        if (!(changed & (1u << ch)))
            continue;
        if (level & (1u << ch)) {
            rise[ch] = now;
        } else {
            width[ch] = (uint16_t)(now - rise[ch]) / 2;
            if (ch == 3)
                fresh = 1;
        }
    }
}

int main(void)
{
    uart0_init(_BV(TXEN0));
    TCCR1B = _BV(CS11);
    RC_MASK_REG = (uint8_t)(0x0F << RC_SHIFT);
    PCICR = _BV(PCIE2);
    sei();
    for (;;) {
        if (!fresh)
            continue;
        uint16_t w[4];
        cli();
        for (uint8_t i = 0; i < 4; i++)
            w[i] = width[i];
        fresh = 0;
        sei();
        put(0xE3);
        put(4);
        for (uint8_t i = 0; i < 4; i++) {
            put(w[i] & 0xFF);
            put(w[i] >> 8);
        }
    }
}
