/* The TWI replayer: runs one recorded client trace (emulators/traces, the table generated into
 * traces.h; which one: EEPROM byte 0) through the TWI at 400 kHz, each step at its time since the
 * start, and reports what it read over USART0: per step 0xA5, 0 (or 1: an address was not acknowledged,
 * the transfer stopped there), the bytes of each read; 0x5A 0x5A at the end. */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <stdint.h>
#include <util/twi.h>

#include "traces.h"

static volatile uint16_t overflows;

ISR(TIMER1_OVF_vect) { overflows++; }

static uint32_t now_us(void) /* Timer1 at 2 MHz, 32 bits with its overflows */
{
    uint16_t hi, lo;
    cli();
    lo = TCNT1;
    hi = overflows;
    if ((TIFR1 & _BV(TOV1)) && lo < 0x8000)
        hi++;
    sei();
    return (((uint32_t)hi << 16) | lo) >> 1;
}

static void put(uint8_t b)
{
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = b;
}

static uint8_t twi(uint8_t control)
{
    TWCR = control | _BV(TWINT) | _BV(TWEN);
    while (!(TWCR & _BV(TWINT))) {
    }
    return TW_STATUS;
}

int main(void)
{
    UBRR0 = 3; /* 500000 baud with U2X */
    UCSR0A = _BV(U2X0);
    UCSR0B = _BV(TXEN0);
    TWBR = 12; /* 400 kHz */
    TCCR1B = _BV(CS11);
    TIMSK1 = _BV(TOIE1);
    sei();
    uint8_t which = eeprom_read_byte(0);
    const uint8_t *p = trace_data + pgm_read_word(&trace_offset[which < TRACE_COUNT ? which : 0]);
    uint32_t due = 0;
    for (;;) {
        uint32_t dt = pgm_read_dword(p);
        uint8_t n = pgm_read_byte(p + 4);
        p += 5;
        if (n == 0xFF)
            break;
        due += dt;
        while ((int32_t)(now_us() - due) < 0) {
        }
        put(0xA5);
        uint8_t nacked = 0;
        uint8_t reads[200]; /* the longest step of the traces reads 70 bytes */
        uint8_t n_reads = 0;
        for (uint8_t i = 0; i < n; i++) {
            uint8_t addr = pgm_read_byte(p), read = pgm_read_byte(p + 1), len = pgm_read_byte(p + 2);
            p += 3;
            const uint8_t *data = p;
            if (!read)
                p += len;
            if (nacked)
                continue;
            twi(_BV(TWSTA));
            uint8_t status = (TWDR = (uint8_t)(addr << 1 | read), twi(0));
            if (status != (read ? TW_MR_SLA_ACK : TW_MT_SLA_ACK)) {
                nacked = 1;
                continue;
            }
            for (uint8_t k = 0; k < len; k++) {
                if (read) {
                    twi(k + 1 < len ? _BV(TWEA) : 0);
                    if (n_reads < sizeof reads)
                        reads[n_reads++] = TWDR;
                } else {
                    TWDR = pgm_read_byte(data + k);
                    twi(0);
                }
            }
        }
        TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
        while (TWCR & _BV(TWSTO)) {
        }
        put(nacked);
        for (uint8_t k = 0; k < n_reads; k++)
            put(reads[k]);
    }
    put(0x5A);
    put(0x5A);
    for (;;) {
    }
}
