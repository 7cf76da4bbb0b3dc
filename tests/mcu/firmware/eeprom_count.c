/* Counts its boots in EEPROM, as a firmware keeps its settings: reads byte 0, writes it back plus one,
 * writes "saved" at bytes 1-5, reports the byte it read over USART0 (500000 baud), then idles (no bus,
 * no pulses). An erased EEPROM reads 0xFF, so a first boot writes 0x00. */
#include <avr/eeprom.h>
#include <avr/io.h>
#include <stdint.h>

int main(void)
{
    uint8_t boots = eeprom_read_byte((const uint8_t *)0);
    eeprom_write_byte((uint8_t *)0, (uint8_t)(boots + 1));
    eeprom_write_block("saved", (void *)1, 5);
    UBRR0 = 3; /* 500000 baud with U2X */
    UCSR0A = _BV(U2X0);
    UCSR0B = _BV(TXEN0);
    UDR0 = boots;
    for (;;) {
    }
}
