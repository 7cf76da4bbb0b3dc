/* Talks to an EEPROM at 0x50 that the rig's board does not have, every millisecond, forever: a bus no chip
 * answers. */
#include <avr/io.h>
#include <util/delay.h>
#include <util/twi.h>

static uint8_t twi(uint8_t control)
{
    TWCR = control | _BV(TWINT) | _BV(TWEN);
    while (!(TWCR & _BV(TWINT))) {
    }
    return TW_STATUS;
}

int main(void)
{
    TWBR = 72; /* 100 kHz */
    for (;;) {
        twi(_BV(TWSTA));
        TWDR = 0x50 << 1;
        if (twi(0) == TW_MT_SLA_ACK) {
            TWDR = 0x00;
            twi(0);
        }
        TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
        while (TWCR & _BV(TWSTO)) {
        }
        _delay_ms(1);
    }
}
