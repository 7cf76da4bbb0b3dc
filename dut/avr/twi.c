/* TWI master (twi.h), against the ATmega2560 datasheet's TWI chapter (status codes of tables 24-3 and
   24-4). SCL = F_CPU / (16 + 2 TWBR 4^TWPS): TWBR 12, TWPS 0 gives 400 kHz at 16 MHz. */
#include "twi.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/twi.h>

#include "board.h"
#include "clock.h"

twi_stats twi_counters;

enum { IDLE, BUSY, DONE, FAILED };
static volatile uint8_t state, error;
static uint8_t sla;
static const uint8_t *wbuf;
static uint8_t *rbuf;
static uint8_t wn, rn;
static volatile uint8_t wi, ri;

#define GO (_BV(TWINT) | _BV(TWEN) | _BV(TWIE))

static void stop(uint8_t result, uint8_t why)
{
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
    error = why;
    state = result;
}

ISR(TWI_vect)
{
    switch (TW_STATUS) {
    case TW_START:
    case TW_REP_START:
        TWDR = (uint8_t)(sla << 1) | (wi < wn ? TW_WRITE : TW_READ);
        TWCR = GO;
        break;
    case TW_MT_SLA_ACK:
    case TW_MT_DATA_ACK:
        if (wi < wn) {
            TWDR = wbuf[wi++];
            TWCR = GO;
        } else if (rn > 0) {
            TWCR = GO | _BV(TWSTA); /* repeated START for the read */
        } else {
            stop(DONE, 0);
        }
        break;
    case TW_MR_SLA_ACK:
        TWCR = rn > 1 ? GO | _BV(TWEA) : GO; /* acknowledge all but the last byte */
        break;
    case TW_MR_DATA_ACK:
        rbuf[ri++] = TWDR;
        TWCR = ri < rn - 1 ? GO | _BV(TWEA) : GO;
        break;
    case TW_MR_DATA_NACK:
        rbuf[ri++] = TWDR;
        stop(DONE, 0);
        break;
    case TW_MT_SLA_NACK:
    case TW_MT_DATA_NACK:
    case TW_MR_SLA_NACK:
        stop(FAILED, 1);
        break;
    case TW_MT_ARB_LOST: /* (= TW_MR_ARB_LOST) the bus is released, no STOP */
        TWCR = _BV(TWINT) | _BV(TWEN);
        error = 3;
        state = FAILED;
        break;
    default: /* TW_BUS_ERROR and anything unexpected */
        stop(FAILED, 3);
        break;
    }
}

void twi_init(void)
{
    PORTD |= _BV(PD0) | _BV(PD1); /* internal pull-ups as well as the GY-86's 4.7k */
    TWSR = 0;                     /* prescaler 1 */
    TWBR = (uint8_t)((BOARD_F_CPU / TWI_HZ - 16) / 2);
    TWCR = _BV(TWEN);
    state = IDLE;
}

/* Nine SCL pulses free a slave that holds SDA low mid-byte; then a STOP by hand. About 50 us. */
void twi_recover(void)
{
    TWCR = 0; /* the TWI lets go of the pins */
    DDRD &= (uint8_t) ~(_BV(PD0) | _BV(PD1));
    PORTD |= _BV(PD0) | _BV(PD1);
    for (uint8_t i = 0; i < 9 && !(PIND & _BV(PD1)); i++) {
        DDRD |= _BV(PD0); /* SCL low (PORTD bit high only matters as input) */
        PORTD &= (uint8_t)~_BV(PD0);
        clock_wait_us(3);
        DDRD &= (uint8_t)~_BV(PD0);
        PORTD |= _BV(PD0);
        clock_wait_us(3);
    }
    /* STOP: SDA low while SCL high, then SDA released */
    PORTD &= (uint8_t)~_BV(PD1);
    DDRD |= _BV(PD1);
    clock_wait_us(3);
    DDRD &= (uint8_t)~_BV(PD1);
    PORTD |= _BV(PD1);
    clock_wait_us(3);
    twi_counters.recoveries++;
    twi_init();
}

int twi_xfer(uint8_t addr, const uint8_t *w, uint8_t nw, uint8_t *r, uint8_t nr)
{
    /* each byte is 9 SCL periods (22.5 us at 400 kHz); allow a stretching slave four times that, and
       the START, address and STOP besides */
    uint32_t limit = 2UL * (200 + 100UL * (nw + nr + 2));
    uint32_t t0 = clock_ticks();
    while (TWCR & _BV(TWSTO)) /* the previous transfer's STOP still on the wire */
        if (clock_ticks() - t0 > 200) {
            twi_counters.timeouts++;
            twi_recover();
            break;
        }
    sla = addr;
    wbuf = w;
    rbuf = r;
    wn = nw;
    rn = nr;
    wi = ri = 0;
    error = 0;
    state = BUSY;
    TWCR = GO | _BV(TWSTA);
    t0 = clock_ticks();
    while (state == BUSY)
        if (clock_ticks() - t0 > limit) {
            TWCR = 0; /* no more interrupts from this transfer */
            state = IDLE;
            twi_counters.timeouts++;
            twi_recover();
            return -2;
        }
    uint8_t s = state, e = error;
    state = IDLE;
    if (s == DONE)
        return 0;
    if (e == 1) {
        twi_counters.nacks++;
        return -1;
    }
    twi_counters.bus_errors++;
    twi_recover();
    return -3;
}
