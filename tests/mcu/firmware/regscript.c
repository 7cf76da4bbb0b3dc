/* Writes what the test put in EEPROM to the I/O registers, in order, then loops: the PWM tests configure
 * any timer in any mode this way (one firmware for all of them). EEPROM: records of a 16-bit data-space
 * address (little-endian) and a byte; address 0xFFFE waits the byte's count of milliseconds (Timer-free:
 * a calibrated busy loop); 0xFFFF ends the script. */
#include <avr/eeprom.h>
#include <stdint.h>
#include <util/delay.h>

int main(void)
{
    for (uint16_t at = 0; at + 3 <= E2END; at += 3) {
        uint16_t addr = eeprom_read_word((const uint16_t *)at);
        uint8_t value = eeprom_read_byte((const uint8_t *)(at + 2));
        if (addr == 0xFFFF)
            break;
        if (addr == 0xFFFE) {
            while (value--)
                _delay_ms(1);
            continue;
        }
        *(volatile uint8_t *)addr = value;
    }
    for (;;) {
    }
}
