/* USART1 receive interrupt (sbus_rx.h): bytes assembled into a frame buffer; a finished frame is copied
   for the loop, which decodes it with the portable sbus_decode. The gap is timed on the clock's timer. */
#include "sbus_rx.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <string.h>
#include <util/atomic.h>

#include "board.h"
#include "clock.h"

static uint8_t buf[SBUS_FRAME], n, spoilt;
static uint32_t last_byte;
static volatile uint8_t ready_bad, ready;
static uint8_t ready_buf[SBUS_FRAME];
static volatile sbus_rx_stats stats;

ISR(USART1_RX_vect)
{
    uint8_t status = UCSR1A, b = UDR1; /* the status belongs to the byte in UDR1: read it first */
    uint32_t now = clock_ticks();
    if (now - last_byte > 2UL * SBUS_GAP_US) {
        n = 0; /* silence: the next byte starts a frame */
        spoilt = 0;
    }
    last_byte = now;
    if (status & (_BV(FE1) | _BV(DOR1) | _BV(UPE1))) {
        stats.byte_errors++;
        spoilt = 1;
    }
    if (n >= SBUS_FRAME)
        return; /* more than a frame without a gap: wait for one */
    buf[n++] = b;
    if (n == SBUS_FRAME) {
        if (ready)
            stats.dropped++;
        memcpy(ready_buf, buf, SBUS_FRAME);
        ready_bad = spoilt;
        ready = 1;
    }
}

void sbus_rx_init(void)
{
    const uint16_t ubrr = BOARD_F_CPU / (16 * SBUS_BAUD) - 1; /* 9: exact */
    UBRR1H = (uint8_t)(ubrr >> 8);
    UBRR1L = (uint8_t)ubrr;
    UCSR1A = 0;
    UCSR1C = _BV(UPM11) | _BV(USBS1) | _BV(UCSZ11) | _BV(UCSZ10); /* even parity, 2 stop, 8 bits */
    UCSR1B = _BV(RXEN1) | _BV(RXCIE1);
}

int sbus_rx_take(sbus_frame *out)
{
    uint8_t f[SBUS_FRAME], bad;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        if (!ready)
            return 0;
        memcpy(f, ready_buf, SBUS_FRAME);
        bad = ready_bad;
        ready = 0;
    }
    if (bad || sbus_decode(f, out) < 0) {
        ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { stats.bad_frames++; }
        return -1;
    }
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { stats.frames++; }
    return 1;
}

sbus_rx_stats sbus_rx_counters(void)
{
    sbus_rx_stats s;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { s = stats; }
    return s;
}
