/* Telemetry out of USART0 (TX0, D1/PE1; the Mega's USB serial) at 500000 baud, 8N1: a ring buffer the
   data-register-empty interrupt drains, so a line costs the loop only its formatting. A line (or a
   binary frame) that does not fit the free space is dropped whole and counted: a torn line would parse
   as garbage. With MSP telemetry the port also receives (RX0, D0/PE0): the requests. */
#ifndef UART0_H
#define UART0_H

#include <stdint.h>

void uart0_init(void);
/* queues a whole line (or binary frames, sent whole); 0, or -1 when it did not fit (dropped, counted) */
int uart0_line(const char *s, uint8_t n);
uint16_t uart0_dropped(void);
void uart0_listen(void);                       /* the receiver on (MSP): bytes kept until taken */
uint8_t uart0_take(uint8_t *buf, uint8_t cap); /* the bytes received since the last take */
void uart0_flush(void); /* waits until everything queued is sent (start-up messages before a reset) */

/* Line building into a caller's buffer: text, integers, and fixed-point numbers (no printf: avr-libc's
   float printf costs 1.5 KB of flash and ~1 ms a number) */
typedef struct {
    char *buf;
    uint8_t n, cap;
} line;
void line_str(line *l, const char *s);
void line_int(line *l, int32_t v);
void line_fixed_digits(line *l, uint32_t v, uint8_t digits); /* v with leading zeros to `digits` */
void line_fixed(line *l, float v, uint8_t decimals);         /* NaN: "nan", beyond +-2e9 units: "inf" */

#endif
