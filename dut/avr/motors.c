/* Timers 3 and 4 in phase-correct PWM with TOP = ICRn (WGM 10), prescaler 8 (board.h): the compare
   registers are double-buffered (updated at TOP), so a write never produces a runt pulse. The timers'
   16-bit registers share one TEMP byte with every other 16-bit access, so writes are done with
   interrupts off. */
#include "motors.h"

#include <avr/io.h>
#include <util/atomic.h>

#include "board.h"

void motors_init(void)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        /* non-inverting on A, B, C (timer 3) and A (timer 4); WGM 10 = WGMn3 + WGMn1; the mode first,
           so the compare registers are written as this mode's (double-buffered) */
        TCCR3A = _BV(COM3A1) | _BV(COM3B1) | _BV(COM3C1) | _BV(WGM31);
        TCCR4A = _BV(COM4A1) | _BV(WGM41);
        TCCR3B = _BV(WGM33);
        TCCR4B = _BV(WGM43);
        ICR3 = PWM_TOP;
        ICR4 = PWM_TOP;
        OCR3A = OCR3B = OCR3C = PWM_MIN_US;
        OCR4A = PWM_MIN_US;
        TCNT3 = 0;
        TCNT4 = 0;
        TCCR3B = _BV(WGM33) | _BV(CS31); /* prescaler 8: both start */
        TCCR4B = _BV(WGM43) | _BV(CS41);
    }
    DDRE |= _BV(PE3) | _BV(PE4) | _BV(PE5); /* D5, D2, D3 */
    DDRH |= _BV(PH3);                       /* D6 */
}

void motors_write_us(uint8_t motor, uint16_t us)
{
    if (us < PWM_MIN_US)
        us = PWM_MIN_US;
    if (us > PWM_MAX_US)
        us = PWM_MAX_US;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        switch (motor) {
        case 0:
            OCR3B = us; /* D2 PE4 */
            break;
        case 1:
            OCR3C = us; /* D3 PE5 */
            break;
        case 2:
            OCR3A = us; /* D5 PE3 */
            break;
        case 3:
            OCR4A = us; /* D6 PH3 */
            break;
        default:
            break;
        }
    }
}

void motors_off(void)
{
    TCCR3A = 0; /* the compare outputs let go of the pins... */
    TCCR4A = 0;
    PORTE &= (uint8_t) ~(_BV(PE3) | _BV(PE4) | _BV(PE5)); /* ...which stay outputs, low */
    PORTH &= (uint8_t)~_BV(PH3);
}
