/* SBUS frames as the RC receiver sends them: 25 bytes, 0x0F, 16 channels of 11 bits LSB first, a flags
   byte (bit 2 frame lost, bit 3 failsafe), 0x00; and a parser that finds frames in a byte stream. */
#include <string.h>

#include "fc.h"

int sbus_decode(const uint8_t f[SBUS_FRAME], sbus_frame *out)
{
    if (f[0] != 0x0F || f[24] != 0x00)
        return -1;
    uint32_t acc = 0; /* up to 18 bits pending: wider than an AVR unsigned */
    unsigned bits = 0, ch = 0;
    for (int i = 1; i <= 22 && ch < 16; i++) {
        acc |= (uint32_t)f[i] << bits;
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
    uint32_t acc = 0;
    unsigned bits = 0, at = 1;
    for (int ch = 0; ch < 16; ch++) {
        acc |= (uint32_t)(in->ch[ch] & 0x7FF) << bits;
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

real sbus_to_unit(uint16_t raw) { return clampd((raw - 992.0) / 819.5, -1.0, 1.0); }

/* MultiWii 2.4's reading of an SBUS value (RX.cpp readSerial_RX: (raw & 0x07FF) / 2 + SBUS_MID_OFFSET,
   the offset 988 in its config.h, "SBUS Mid-Point at 1500"; then, "the SBUS data provides only about 75%
   of the actual RX output pulse width", each value moved a quarter further from MIDRC 1500, in integer
   steps), then its 1000..2000 us as -1..1. Signed 32-bit on purpose: where int is 16 bits (the AVR) a
   uint16_t promotes to unsigned, and a value under 1024 would wrap to a stick at full travel the other
   way. */
real sbus_to_unit_multiwii(uint16_t raw)
{
    int32_t us = (int32_t)(raw & 0x7FF) / 2 + 988;
    us = us < 1500 ? us - (1500 - us) / 4 : us + (us - 1500) / 4;
    return clampd((us - 1500) / 500.0, -1.0, 1.0);
}
