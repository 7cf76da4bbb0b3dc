/* The I2C1 master with ST's HAL polling sequences (HAL_I2C_Mem_Read/Write of the STM32F4 HAL: one byte
   with ACK cleared before ADDR is, two with POS, N with the last three taken at BTF), each wait bounded;
   a timeout ends in a software reset of the controller and a bus unstick (nine SCL pulses by GPIO, then
   a STOP by hand). Every failure is counted for the telemetry. The same interface as the AVR build's
   twi.h (src/sensors.c uses it). */
#ifndef TWI_H
#define TWI_H

#include <stdint.h>

typedef struct {
    uint16_t nacks;      /* address or data not acknowledged */
    uint16_t timeouts;   /* a flag that did not come in its time (a stuck bus) */
    uint16_t bus_errors; /* BERR or ARLO in SR1 */
    uint16_t recoveries; /* bus recoveries done */
} twi_stats;

extern twi_stats twi_counters;

void twi_init(void);
/* write wn bytes, then (repeated START) read rn bytes, at 7-bit addr: 0, -1 NACK, -2 timeout, -3 bus
   error */
int twi_xfer(uint8_t addr, const uint8_t *w, uint8_t wn, uint8_t *r, uint8_t rn);
void twi_recover(void);

#endif
