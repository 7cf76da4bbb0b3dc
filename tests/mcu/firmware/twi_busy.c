/* Writes TWCR while the TWI is busy, in the ways the datasheet allows (ATmega2560 2549Q and ATmega328P,
 * chapter "2-wire Serial Interface"), and reports what it saw over USART0 (500000 baud). Which case:
 * EEPROM byte 0. Every wait for TWINT gives up after WAIT_TRIES polls, as MultiWii's does: it then
 * resets TWCR (TWCR = 0) and counts the failure. The report: the case's bytes below, then 0x5A 0x5A.
 *
 * 0 STOP, then START at once, ROUNDS times (MultiWii's i2c_stop(); i2c_rep_start();): per round the
 *   START's status or 0 for a wait given up; then the reads of WHO_AM_I that followed (0x68 each).
 * 1 STOP and START in one write (TWINT|TWSTA|TWSTO), ROUNDS times: the same report.
 * 2 TWEA changed while a byte is being received: the first byte asked with TWEA = 0 and then set, the
 *   second asked with TWEA = 1 and then cleared: the statuses of SLA+R and the two bytes.
 * 3 STOP, then STOP again while the first is on the bus: TWSTO after the wait (0: cleared), TWINT (0:
 *   not set after a STOP), the next START's status.
 * 4 START requested while the address byte is on the bus (TWINT written while it is 0): the status
 *   that ends the byte, then the next byte's.
 * 5 START, then TWCR = 0 before TWINT (a wait given up): the next START's status. */
#include <avr/eeprom.h>
#include <avr/io.h>
#include <stdint.h>
#include <util/twi.h>

#define ROUNDS 100
#define WAIT_TRIES 255
#define MPU 0x68
#define WHO_AM_I 0x75

static void put(uint8_t b)
{
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = b;
}

/* TWINT within WAIT_TRIES polls: the status; else TWCR reset and 0 */
static uint8_t wait_twint(void)
{
    for (uint8_t tries = WAIT_TRIES; tries; tries--)
        if (TWCR & _BV(TWINT))
            return TW_STATUS;
    TWCR = 0;
    return 0;
}

static uint8_t twi(uint8_t control)
{
    TWCR = control | _BV(TWINT) | _BV(TWEN);
    return wait_twint();
}

static void stop(void) { TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO); }

static void wait_stopped(void)
{
    for (uint8_t tries = WAIT_TRIES; tries && (TWCR & _BV(TWSTO)); tries--) {
    }
}

/* after a START: SLA+W, the register, a repeated START, SLA+R, one byte NACKed; the byte (0 on a failure) */
static uint8_t read_who_am_i(void)
{
    TWDR = MPU << 1;
    if (twi(0) != TW_MT_SLA_ACK)
        return 0;
    TWDR = WHO_AM_I;
    if (twi(0) != TW_MT_DATA_ACK)
        return 0;
    if (twi(_BV(TWSTA)) != TW_REP_START)
        return 0;
    TWDR = MPU << 1 | 1;
    if (twi(0) != TW_MR_SLA_ACK)
        return 0;
    if (twi(0) != TW_MR_DATA_NACK)
        return 0;
    return TWDR;
}

static void rounds(uint8_t together)
{
    uint8_t starts[ROUNDS], reads[ROUNDS];
    if (twi(_BV(TWSTA)) != TW_START)
        return;
    for (uint8_t i = 0; i < ROUNDS; i++) {
        reads[i] = read_who_am_i();
        if (together) {
            starts[i] = twi(_BV(TWSTA) | _BV(TWSTO));
        } else {
            stop();
            starts[i] = twi(_BV(TWSTA));
        }
        if (!starts[i] && twi(_BV(TWSTA)) != TW_START) /* (a wait given up: the bus again) */
            return;
    }
    stop();
    for (uint8_t i = 0; i < ROUNDS; i++)
        put(starts[i]);
    for (uint8_t i = 0; i < ROUNDS; i++)
        put(reads[i]);
}

static void twea_while_receiving(void)
{
    twi(_BV(TWSTA));
    TWDR = MPU << 1;
    twi(0);
    TWDR = WHO_AM_I;
    twi(0);
    twi(_BV(TWSTA));
    TWDR = MPU << 1 | 1;
    put(twi(0));
    TWCR = _BV(TWINT) | _BV(TWEN); /* asked without the ACK ... */
    TWCR = _BV(TWEN) | _BV(TWEA);  /* ... then TWEA set, the byte still on the bus */
    put(wait_twint());
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWEA); /* asked with the ACK ... */
    TWCR = _BV(TWEN);                          /* ... then TWEA cleared */
    put(wait_twint());
    stop();
    wait_stopped();
}

static void stop_during_stop(void)
{
    twi(_BV(TWSTA));
    TWDR = MPU << 1;
    twi(0);
    stop();
    stop();
    wait_stopped();
    put(TWCR & _BV(TWSTO));
    put(TWCR & _BV(TWINT));
    put(twi(_BV(TWSTA)));
    stop();
    wait_stopped();
}

static void start_during_byte(void)
{
    twi(_BV(TWSTA));
    TWDR = MPU << 1;
    TWCR = _BV(TWINT) | _BV(TWEN);
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTA); /* the address byte is on the bus */
    put(wait_twint());
    TWDR = WHO_AM_I;
    put(twi(0));
    stop();
    wait_stopped();
}

static void abandoned_wait(void)
{
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTA);
    TWCR = 0;
    put(twi(_BV(TWSTA)));
    stop();
    wait_stopped();
}

int main(void)
{
    UBRR0 = 3; /* 500000 baud with U2X */
    UCSR0A = _BV(U2X0);
    UCSR0B = _BV(TXEN0);
    TWBR = 12; /* 400 kHz */
    switch (eeprom_read_byte(0)) {
    case 0:
        rounds(0);
        break;
    case 1:
        rounds(1);
        break;
    case 2:
        twea_while_receiving();
        break;
    case 3:
        stop_during_stop();
        break;
    case 4:
        start_during_byte();
        break;
    case 5:
        abandoned_wait();
        break;
    default:
        break;
    }
    put(0x5A);
    put(0x5A);
    for (;;) {
    }
}
