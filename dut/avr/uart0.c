/* USART0 transmit ring buffer and line formatting (uart0.h). */
#include "uart0.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <util/atomic.h>

#include "board.h"

#define TXBUF 256 /* two lines of ~110 bytes; a 256 buffer lets the index wrap as a uint8_t */
static uint8_t tx[TXBUF];
static volatile uint8_t head, tail; /* head: next free; tail: next to send */
static uint16_t dropped;

ISR(USART0_UDRE_vect)
{
    if (head == tail) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = tx[tail];
    tail = (uint8_t)(tail + 1);
}

void uart0_init(void)
{
    const uint16_t ubrr = BOARD_F_CPU / (8 * TELEMETRY_BAUD) - 1; /* U2X: 3, exact */
    UBRR0H = (uint8_t)(ubrr >> 8);
    UBRR0L = (uint8_t)ubrr;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = _BV(TXEN0);
}

int uart0_line(const char *s, uint8_t n)
{
    uint8_t free_;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { free_ = (uint8_t)(tail - head - 1); }
    if (n > free_) {
        dropped++;
        return -1;
    }
    uint8_t h = head;
    for (uint8_t i = 0; i < n; i++)
        tx[h++] = (uint8_t)s[i];
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        head = h;
        UCSR0B |= _BV(UDRIE0);
    }
    return 0;
}

uint16_t uart0_dropped(void) { return dropped; }

/* What the telemetry port receives (MSP requests): a ring the receive interrupt fills; bytes that find it
   full are lost (the requester asks again) */
#define RXBUF 64
static uint8_t rx[RXBUF];
static volatile uint8_t rx_head, rx_tail;

ISR(USART0_RX_vect)
{
    uint8_t b = UDR0;
    uint8_t next = (uint8_t)((rx_head + 1) % RXBUF);
    if (next != rx_tail) {
        rx[rx_head] = b;
        rx_head = next;
    }
}

void uart0_listen(void) { UCSR0B |= _BV(RXEN0) | _BV(RXCIE0); }

uint8_t uart0_take(uint8_t *buf, uint8_t cap)
{
    uint8_t n = 0;
    while (n < cap && rx_tail != rx_head) {
        buf[n++] = rx[rx_tail];
        rx_tail = (uint8_t)((rx_tail + 1) % RXBUF);
    }
    return n;
}

void uart0_flush(void)
{
    while (head != tail)
        ;
    while (!(UCSR0A & _BV(UDRE0)))
        ;
}

static void put(line *l, char c)
{
    if (l->n < l->cap)
        l->buf[l->n++] = c;
}

void line_str(line *l, const char *s)
{
    while (*s)
        put(l, *s++);
}

/* avr-libc's ultoa divides by ten in hand-written assembly: a third of the cycles of a C loop of 32-bit
   divisions (the telemetry line has 17 numbers) */
static void put_u32(line *l, uint32_t v, uint8_t min_digits)
{
    char d[11];
    ultoa(v, d, 10);
    for (uint8_t k = (uint8_t)strlen(d); k < min_digits; k++)
        put(l, '0');
    line_str(l, d);
}

void line_fixed_digits(line *l, uint32_t v, uint8_t digits) { put_u32(l, v, digits); }

void line_int(line *l, int32_t v)
{
    if (v < 0) {
        put(l, '-');
        put_u32(l, (uint32_t)-v, 1);
    } else {
        put_u32(l, (uint32_t)v, 1);
    }
}

void line_fixed(line *l, float v, uint8_t decimals)
{
    static const uint16_t pow10[] = { 1, 10, 100, 1000, 10000 };
    if (isnan(v)) {
        line_str(l, "nan");
        return;
    }
    uint16_t scale = pow10[decimals > 4 ? 4 : decimals];
    float s = fabsf(v) * scale + 0.5f;
    if (!(s < 2e9f)) {
        line_str(l, v < 0 ? "-inf" : "inf");
        return;
    }
    uint32_t u = (uint32_t)s;
    if (v < 0 && u)
        put(l, '-');
    put_u32(l, u / scale, 1);
    if (decimals) {
        put(l, '.');
        put_u32(l, u % scale, decimals);
    }
}
