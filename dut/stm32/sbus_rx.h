/* SBUS on USART1 RX (PA10): 100000 baud, 8 data bits, even parity, 2 stop bits, the signal un-inverted
   before the pin. A frame is found by the gap after it (the USART's IDLE): 25 bytes since the last gap
   make it. A parity or framing error or an overrun the USART shows at the gap spoils its frame. */
#ifndef SBUS_RX_H
#define SBUS_RX_H

#include <stdint.h>

#include "fc.h"

typedef struct {
    uint16_t frames;      /* complete frames handed over */
    uint16_t bad_frames;  /* a wrong header or footer, or a byte error inside */
    uint16_t byte_errors; /* parity, framing, overrun */
    uint16_t dropped;     /* frames overwritten before the loop took them */
} sbus_rx_stats;

void sbus_rx_init(void);
/* The newest complete frame since the last call, decoded: 1; none: 0; one that was bad: -1. */
int sbus_rx_take(sbus_frame *out);
sbus_rx_stats sbus_rx_counters(void);

#endif
