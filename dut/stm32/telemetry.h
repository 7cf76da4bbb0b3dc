/* Telemetry out of USART6 TX (PC6) at 500000 baud 8N1: the Linux FC's line "T t=... roll=... pitch=...
   yaw=... alt=... armed= rc= gyro_fault= loop_us= max_us= overruns=" (the keys the rig reads), then the
   AVR build's own counters (cfg, twi_err, twi_rec, sbus_ok, sbus_bad), and "# fc: ..." messages. */
#ifndef TELEMETRY_H
#define TELEMETRY_H

#include <stdint.h>

#include "flight.h"
#include "sbus_rx.h"
#include "twi.h"

typedef struct {
    uint32_t loop_us, max_us, overruns;
    const char *cfg;
    twi_stats twi;
    sbus_rx_stats sbus;
} tel_counters;

void telemetry_init(void);
void telemetry_send(const char *s, unsigned n);   /* bytes queued for the USART (all of them, or none when full) */
void telemetry_say(const char *a, const char *b); /* "# fc: " a b "\n" */
void telemetry_line(double t, const flight *fl, const tel_counters *k);

#endif
