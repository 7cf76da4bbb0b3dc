/* The telemetry line: the Linux FC's "T t=... roll=... pitch=... yaw=... alt=... armed= rc= gyro_fault=
   loop_us= max_us= overruns=" (the keys the rig reads: rig/runner.py TELEMETRY_KEYS), then the AVR's
   own: cfg (the configuration's source: eeprom, or why the defaults), twi_err, twi_rec, sbus_ok,
   sbus_bad, tel_drop. t is the firmware's clock, seconds since reset, to 0.1 ms. */
#ifndef TELEMETRY_H
#define TELEMETRY_H

#include <stdint.h>

#include "flight.h"
#include "sbus_rx.h"
#include "twi.h"

#define TELEMETRY_LINE 220

typedef struct {
    uint32_t loop_ticks, max_ticks, overruns; /* 0.5 us ticks */
    const char *cfg;
    twi_stats twi;
    sbus_rx_stats sbus;
    uint16_t tel_dropped;
} tel_counters;

/* formats into buf (TELEMETRY_LINE bytes), returns the length including the '\n'; the time is
   wraps * 2^32 + ticks clock ticks */
uint8_t telemetry_line(char *buf, uint16_t wraps, uint32_t ticks, const flight *fl, const tel_counters *k);

#endif
