/* The MS5611 as its driver needs it, bus aside: the PROM's CRC-4 and the compensation (datasheet and
   AN520, integer exactly as published), and the conversion cycle (D2 temperature, then D1 pressure,
   OSR 4096), which reaches the chip through the caller's bus and clock so it can be tested alone. */
#include <string.h>

#include "fc.h"

unsigned ms5611_crc4(const uint16_t prom[8])
{
    uint16_t w[8];
    memcpy(w, prom, sizeof w);
    w[7] &= 0xFF00; /* the CRC nibble itself is not covered */
    unsigned rem = 0;
    for (int cnt = 0; cnt < 16; cnt++) {
        rem ^= (cnt & 1) ? (w[cnt >> 1] & 0x00FF) : (unsigned)(w[cnt >> 1] >> 8);
        for (int bit = 0; bit < 8; bit++)
            rem = (rem & 0x8000) ? ((rem << 1) ^ 0x3000) & 0xFFFF : (rem << 1) & 0xFFFF;
    }
    return (rem >> 12) & 0xF;
}

void ms5611_compensate(const uint16_t c[8], uint32_t d1, uint32_t d2, int32_t *p, int32_t *temp)
{
    int64_t dt = (int64_t)d2 - ((int64_t)c[5] << 8);
    int64_t t = 2000 + dt * c[6] / ((int64_t)1 << 23);
    int64_t off = ((int64_t)c[2] << 16) + ((int64_t)c[4] * dt) / ((int64_t)1 << 7);
    int64_t sens = ((int64_t)c[1] << 15) + ((int64_t)c[3] * dt) / ((int64_t)1 << 8);
    if (t < 2000) { /* second order, datasheet */
        int64_t t2 = dt * dt / ((int64_t)1 << 31);
        int64_t off2 = 5 * (t - 2000) * (t - 2000) / 2;
        int64_t sens2 = 5 * (t - 2000) * (t - 2000) / 4;
        if (t < -1500) {
            off2 += 7 * (t + 1500) * (t + 1500);
            sens2 += 11 * (t + 1500) * (t + 1500) / 2;
        }
        t -= t2;
        off -= off2;
        sens -= sens2;
    }
    *p = (int32_t)(((int64_t)d1 * sens / ((int64_t)1 << 21) - off) / ((int64_t)1 << 15));
    *temp = (int32_t)t;
}

/* A conversion takes at most 9.04 ms at OSR 4096; a little margin, counted from when the command was
   sent (not from the loop's start: a loop preempted between the two read too early). */
#define MS5611_CONV_S 0.0095

static int ms5611_convert(ms5611_dev *d, const ms5611_bus *bus)
{
    uint8_t cmd = d->phase ? 0x48 : 0x58; /* D1 or D2, OSR 4096 */
    if (bus->xfer(bus->ctx, &cmd, 1, NULL, 0) < 0)
        return -1;
    d->started = bus->clock(bus->ctx);
    return 0;
}

int ms5611_poll(ms5611_dev *d, const ms5611_bus *bus, int32_t *p, int32_t *t)
{
    if (d->started == 0)
        return ms5611_convert(d, bus);
    if (bus->clock(bus->ctx) - d->started < MS5611_CONV_S)
        return 0;
    uint8_t zero = 0x00, b[3];
    if (bus->xfer(bus->ctx, &zero, 1, b, 3) < 0)
        return -1;
    uint32_t v = (uint32_t)b[0] << 16 | (uint32_t)b[1] << 8 | b[2];
    if (v == 0) { /* the datasheet's "conversion not finished": no reading; convert again */
        d->not_ready++;
        return ms5611_convert(d, bus);
    }
    int ready = 0;
    if (d->phase) {
        d->d1 = v;
        if (d->have_d2) {
            ms5611_compensate(d->prom, d->d1, d->d2, p, t);
            ready = *p >= MS5611_P_MIN && *p <= MS5611_P_MAX; /* outside the chip's range: not a reading */
        }
    } else {
        d->d2 = v;
        d->have_d2 = 1;
    }
    d->phase ^= 1;
    return ms5611_convert(d, bus) < 0 ? -1 : ready;
}
