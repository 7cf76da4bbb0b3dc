/* The firmware's clock: timer 1 free-running at 2 MHz (prescaler 8) and its overflows counted, so a
   32-bit tick count wraps after 35 minutes and a seconds value (double) never does in a flight. */
#ifndef CLOCK_H
#define CLOCK_H

#include <stdint.h>

void clock_init(void);
uint32_t clock_ticks(void);      /* 0.5 us ticks since clock_init (wraps after 2147 s; differences stay right) */
double clock_seconds(void);      /* seconds since reset, for telemetry and the flight logic */
void clock_wait_us(uint16_t us); /* busy wait (start-up only: the chips' reset times) */

#endif
