/* The TWI master, interrupt-driven at 400 kHz: a transfer (write, then a repeated START and a read) runs
   in the TWI interrupt while the caller waits for it with a timeout; a timeout or a bus error ends in a
   bus recovery (nine SCL pulses and a STOP by hand, as a slave stuck mid-byte needs). Every failure is
   counted: the counters go out in the telemetry. */
#ifndef TWI_H
#define TWI_H

#include <stdint.h>

typedef struct {
    uint16_t nacks;      /* address or data not acknowledged */
    uint16_t timeouts;   /* a transfer that did not finish in its time (a stretched or stuck bus) */
    uint16_t bus_errors; /* illegal START/STOP seen by the TWI, or arbitration lost */
    uint16_t recoveries; /* bus recoveries done */
} twi_stats;

extern twi_stats twi_counters;

void twi_init(void);
/* write wn bytes, then (repeated START) read rn bytes, at 7-bit addr: 0, -1 NACK, -2 timeout, -3 bus
   error. Up to 255 bytes each way; buffers must stay valid until it returns (it waits). */
int twi_xfer(uint8_t addr, const uint8_t *w, uint8_t wn, uint8_t *r, uint8_t rn);
void twi_recover(void);

#endif
