/* An interrupt-driven TWI transfer while the CPU sleeps (idle mode): addresses the MPU-6050 once, then
 * sleeps for ever with interrupts on. The TWI's interrupt must wake it on time. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <util/twi.h>

static volatile uint8_t done;

ISR(TWI_vect)
{
    if (TW_STATUS == TW_START) {
        TWDR = 0x68 << 1;
        TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWIE);
    } else {
        TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
        done = 1;
    }
}

int main(void)
{
    TWBR = 12; /* 400 kHz: 40 cycles a bit */
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei();
    TWCR = _BV(TWINT) | _BV(TWSTA) | _BV(TWEN) | _BV(TWIE);
    for (;;)
        sleep_mode();
}
