/* Timer 1 as the clock (clock.h). The overflow count and the counter are read together with interrupts
   off; an overflow pending while they are read (TOV1 set, counter already small) is counted here. */
#include "clock.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

static volatile uint16_t overflows;
static uint32_t wraps; /* clock_seconds: 2^32-tick wraps seen, for a clock past 35 minutes */
static uint32_t last;

ISR(TIMER1_OVF_vect) { overflows++; }

void clock_init(void)
{
    TCCR1A = 0;
    TCCR1B = _BV(CS11); /* normal mode, prescaler 8 */
    TCNT1 = 0;
    TIFR1 = _BV(TOV1);
    TIMSK1 = _BV(TOIE1);
}

uint32_t clock_ticks(void)
{
    uint16_t hi, lo;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        hi = overflows;
        lo = TCNT1;
        if ((TIFR1 & _BV(TOV1)) && lo < 0x8000)
            hi++;
    }
    return (uint32_t)hi << 16 | lo;
}

double clock_seconds(void)
{
    uint32_t t = clock_ticks();
    if (t < last)
        wraps++;
    last = t;
    return (double)wraps * 2147.483648 + (double)t / 2000000.0;
}

void clock_wait_us(uint16_t us)
{
    uint32_t t0 = clock_ticks();
    while (clock_ticks() - t0 < 2UL * us)
        ;
}
