/* Polling loops of every kind the engine's polling-loop skip proves (rig/mcu/polling.c), one kind per run:
 * EEPROM byte 0 says which. Each waits, then sends a byte on USART0 (115200 8N1, each byte's send itself
 * a UDRE0 poll), so the tests see when each wait ended; the same runs with the skip on and off must give
 * the same bytes at the same cycles and the same machine at the end.
 *   0 TIFR:  Timer2 (normal, clk/64) overflows polled on TOV2; 'T' every 10 overflows (10.24 ms);
 *   1 TCNT:  Timer1 (normal, clk/8) read as a 16-bit counter, 'C' every 5000 counts (2.5 ms), then
 *            Timer0 (normal, clk/256) read until it passes 200 ('c');
 *   2 flag:  a byte in RAM set by Timer1's compare A interrupt (CTC, clk/8, OCR1A 9999: 5 ms), 'F';
 *   3 TWINT: a START and an address nobody answers on the TWI at 100 kHz, TWINT polled after each, 'W'
 *            with the address status (0x20: SLA+W not acknowledged), then a STOP;
 *   4 UCSR0A: a wait for a byte on USART0 (RXC0), echoed back;
 *   5 PIND:  a wait for PD3 high ('P'), then low ('p'), the pin driven by the test;
 *   6 TWINT counted: mode 3's bus at 400 kHz, TWINT polled as MultiWii does (a count from 255, the wait
 *            given up when it runs out), 'w' with the status and the count left; the byte ends first;
 *   7 TWINT counted out: the same wait with the TWI never started (TWINT never comes): the count runs out,
 *            'e' with the number of waits given up so far.
 * Any other value: an empty loop (a hang). */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

static volatile uint8_t flag;

ISR(TIMER1_COMPA_vect) { flag = 1; }

static void send(uint8_t b)
{
    while (!(UCSR0A & _BV(UDRE0)))
        ;
    UDR0 = b;
}

static void twi_wait(void)
{
    while (!(TWCR & _BV(TWINT)))
        ;
}

static uint8_t errors;

/* MultiWii 2.4's waitTransmissionI2C: the count left (0: given up, the TWI turned off) */
static uint8_t twi_wait_counted(uint8_t twcr)
{
    uint8_t count = 255;
    TWCR = twcr;
    while (!(TWCR & _BV(TWINT))) {
        if (--count == 0) {
            TWCR = 0;
            errors++;
            break;
        }
    }
    return count;
}

int main(void)
{
    uint8_t mode = eeprom_read_byte((const uint8_t *)0);
    UBRR0 = 8; /* 115200 at 16 MHz (U2X0 off: 111111 baud, as Arduino's) */
    UCSR0B = _BV(TXEN0) | _BV(RXEN0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    send('0' + mode);
    if (mode == 0) {
        TCCR2A = 0;
        TCCR2B = _BV(CS22); /* clk/64 */
        for (;;) {
            for (uint8_t i = 0; i < 10; i++) {
                while (!(TIFR2 & _BV(TOV2)))
                    ;
                TIFR2 = _BV(TOV2);
            }
            send('T');
        }
    }
    if (mode == 1) {
        TCCR1A = 0;
        TCCR1B = _BV(CS11); /* clk/8 */
        TCCR0A = 0;
        TCCR0B = _BV(CS02); /* clk/256 */
        for (;;) {
            uint16_t t0 = TCNT1;
            while ((uint16_t)(TCNT1 - t0) < 5000)
                ;
            send('C');
            TCNT0 = 0;
            while (TCNT0 < 200)
                ;
            send('c');
        }
    }
    if (mode == 2) {
        OCR1A = 9999;
        TCCR1A = 0;
        TCCR1B = _BV(WGM12) | _BV(CS11); /* CTC, clk/8 */
        TIMSK1 = _BV(OCIE1A);
        sei();
        for (;;) {
            while (!flag)
                ;
            flag = 0;
            send('F');
        }
    }
    if (mode == 3) {
        TWBR = 72; /* 100 kHz at 16 MHz, prescaler 1 */
        for (;;) {
            TWCR = _BV(TWINT) | _BV(TWSTA) | _BV(TWEN);
            twi_wait();
            TWDR = 0x7E << 1; /* an address no chip has */
            TWCR = _BV(TWINT) | _BV(TWEN);
            twi_wait();
            send('W');
            send(TWSR & 0xF8);
            TWCR = _BV(TWINT) | _BV(TWSTO) | _BV(TWEN);
            for (volatile uint16_t i = 0; i < 200; i++)
                ;
        }
    }
    if (mode == 4) {
        for (;;) {
            while (!(UCSR0A & _BV(RXC0)))
                ;
            send(UDR0);
        }
    }
    if (mode == 5) {
        for (;;) {
            while (!(PIND & _BV(PD3)))
                ;
            send('P');
            while (PIND & _BV(PD3))
                ;
            send('p');
        }
    }
    if (mode == 6) {
        TWBR = 12; /* 400 kHz */
        for (;;) {
            uint8_t left = twi_wait_counted(_BV(TWINT) | _BV(TWSTA) | _BV(TWEN));
            TWDR = 0x7E << 1;
            left = twi_wait_counted(_BV(TWINT) | _BV(TWEN));
            send('w');
            send(TWSR & 0xF8);
            send(left);
            TWCR = _BV(TWINT) | _BV(TWSTO) | _BV(TWEN);
            for (volatile uint16_t i = 0; i < 200; i++)
                ;
        }
    }
    if (mode == 7) {
        for (;;) {
            twi_wait_counted(0);
            send('e');
            send(errors);
        }
    }
    for (;;)
        ;
}
