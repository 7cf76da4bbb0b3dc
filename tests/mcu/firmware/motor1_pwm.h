/* Motor 1's ESC output as the AVR test firmwares drive it (pulse_stop.c, adc_motor.c): ATmega2560 Timer3
 * OC3B (PE4, the Mega's D2), ATmega328P Timer1 OC1A (PB1, the Pro Mini's D9); both phase-correct PWM,
 * TOP = ICR = 2040 at a 0.5 us tick (a 2.04 ms period): OCR_MOTOR = N gives N us wide pulses. */
#ifndef MOTOR1_PWM_H
#define MOTOR1_PWM_H

#include <avr/io.h>
#include <stdint.h>

#if defined(__AVR_ATmega2560__)
#define OCR_MOTOR OCR3B
#else
#define OCR_MOTOR OCR1A
#endif

static inline void motor1_start(uint16_t us)
{
#if defined(__AVR_ATmega2560__)
    DDRE |= _BV(4);
    ICR3 = 2040;
    OCR3B = us;
    TCCR3A = _BV(COM3B1) | _BV(WGM31);
    TCCR3B = _BV(WGM33) | _BV(CS31);
#else
    DDRB |= _BV(1);
    ICR1 = 2040;
    OCR1A = us;
    TCCR1A = _BV(COM1A1) | _BV(WGM11);
    TCCR1B = _BV(WGM13) | _BV(CS11);
#endif
}

/* The compare output disconnected: no more pulses, the pin left as it is */
static inline void motor1_stop(void)
{
#if defined(__AVR_ATmega2560__)
    TCCR3A = _BV(WGM31);
#else
    TCCR1A = _BV(WGM11);
#endif
}

#endif
