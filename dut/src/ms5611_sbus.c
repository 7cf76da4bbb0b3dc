/* Bytes-to-numbers maths the drivers need: the MS5611's CRC-4 and compensation (datasheet and AN520,
   integer exactly as published), and SBUS frames (25 bytes: 0x0F, 16 channels of 11 bits LSB first,
   a flags byte, 0x00). */
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
    int64_t t = 2000 + dt * c[6] / (1 << 23);
    int64_t off = ((int64_t)c[2] << 16) + ((int64_t)c[4] * dt) / (1 << 7);
    int64_t sens = ((int64_t)c[1] << 15) + ((int64_t)c[3] * dt) / (1 << 8);
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
    *p = (int32_t)(((int64_t)d1 * sens / (1 << 21) - off) / (1 << 15));
    *temp = (int32_t)t;
}

int sbus_decode(const uint8_t f[SBUS_FRAME], sbus_frame *out)
{
    if (f[0] != 0x0F || f[24] != 0x00)
        return -1;
    unsigned acc = 0, bits = 0, ch = 0;
    for (int i = 1; i <= 22 && ch < 16; i++) {
        acc |= (unsigned)f[i] << bits;
        bits += 8;
        while (bits >= 11 && ch < 16) {
            out->ch[ch++] = acc & 0x7FF;
            acc >>= 11;
            bits -= 11;
        }
    }
    out->frame_lost = (f[23] >> 2) & 1;
    out->failsafe = (f[23] >> 3) & 1;
    return 0;
}

void sbus_encode(const sbus_frame *in, uint8_t f[SBUS_FRAME])
{
    memset(f, 0, SBUS_FRAME);
    f[0] = 0x0F;
    unsigned acc = 0, bits = 0, at = 1;
    for (int ch = 0; ch < 16; ch++) {
        acc |= (unsigned)(in->ch[ch] & 0x7FF) << bits;
        bits += 11;
        while (bits >= 8) {
            f[at++] = acc & 0xFF;
            acc >>= 8;
            bits -= 8;
        }
    }
    f[23] = (uint8_t)((in->frame_lost ? 4 : 0) | (in->failsafe ? 8 : 0));
}

void sbus_parser_init(sbus_parser *p) { memset(p, 0, sizeof *p); }

int sbus_feed(sbus_parser *p, const uint8_t *data, size_t n, sbus_frame *out)
{
    int got = 0;
    for (size_t i = 0; i < n; i++) {
        if (p->n == 0 && data[i] != 0x0F) {
            p->errors++; /* garbage between frames */
            continue;
        }
        p->buf[p->n++] = data[i];
        if (p->n < SBUS_FRAME)
            continue;
        sbus_frame f;
        if (sbus_decode(p->buf, &f) == 0) {
            *out = f;
            got = 1;
            p->frames++;
            p->n = 0;
        } else { /* resynchronise: drop the false header, rescan what followed it */
            p->errors++;
            uint8_t rest[SBUS_FRAME];
            size_t k = p->n - 1;
            memcpy(rest, p->buf + 1, k);
            p->n = 0;
            got |= sbus_feed(p, rest, k, out);
        }
    }
    return got;
}

double sbus_to_unit(uint16_t raw) { return clampd((raw - 992.0) / 819.5, -1.0, 1.0); }
