/* A firmware with no bus and no motors, for the hang check; what it does is EEPROM byte 0:
 *   0xFF (erased) or 0: toggles PB0 (an output) every 10 ms, as a status LED blinks;
 *   1: sends 'x' on USART0 (115200 8N1) every 100 ms;
 *   2: waits for a byte on USART0 (polling RXC0), then toggles PB0 every 10 ms;
 *   3: reads EEPROM byte 1 until it is 0x5A (a firmware waiting for a configuration it likes), then
 *      toggles PB0 every 10 ms. */
#include "uart0_115200.h"
#include <avr/eeprom.h>
#include <avr/io.h>
#include <stdint.h>
#include <util/delay.h>

static void blink(void)
{
    DDRB |= _BV(0);
    for (;;) {
        PORTB ^= _BV(0);
        _delay_ms(10);
    }
}

int main(void)
{
    uint8_t mode = eeprom_read_byte((const uint8_t *)0);
    uart0_init(_BV(RXEN0) | _BV(TXEN0));
    if (mode == 1) {
        for (;;) {
            UDR0 = 'x';
            _delay_ms(100);
        }
    }
    if (mode == 2) {
        while (!(UCSR0A & _BV(RXC0))) {
        }
        (void)UDR0;
    }
    if (mode == 3) {
        volatile uint16_t where = 1; /* (read again each time: avr-libc's eeprom_read_byte is pure) */
        while (eeprom_read_byte((const uint8_t *)where) != 0x5A) {
        }
    }
    blink();
}
