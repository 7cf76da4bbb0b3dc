/* USART0 at 115200 baud 8N1 for the MCU tier's test firmwares that talk to the rig: UBRR 16 with U2X
 * (2.1 % off, as on the hardware, at 16 MHz), and a byte sent once the data register is empty. */
#ifndef UART0_115200_H
#define UART0_115200_H

#include <avr/io.h>
#include <stdint.h>

/* enables: TXEN0, and RXEN0 (and RXCIE0) for a firmware that also listens */
static inline void uart0_init(uint8_t enables)
{
    UBRR0 = 16;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    UCSR0B = enables;
}

static inline void put(uint8_t b)
{
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = b;
}

#endif
