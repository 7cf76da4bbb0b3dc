/* SBUS out: see sbus_out.h. */
#include "sbus_out.h"

#include <string.h>

void sbus_encode(const uint16_t ch[SBUS_CHANNELS], uint8_t flags, uint8_t out[SBUS_FRAME])
{
    memset(out, 0, SBUS_FRAME);
    out[0] = 0x0F;
    unsigned bit = 0;
    for (int i = 0; i < SBUS_CHANNELS; i++) {
        uint32_t v = ch[i] & 0x7FFu;
        for (int b = 0; b < 11; b++, bit++)
            if (v >> b & 1u)
                out[1 + bit / 8] |= (uint8_t)(1u << (bit % 8));
    }
    out[23] = flags;
    out[24] = 0x00;
}

void sbus_out_init(struct sbus_out *s, uint32_t period_us)
{
    memset(s, 0, sizeof *s);
    s->period_us = period_us;
}

void sbus_out_set(struct sbus_out *s, const uint16_t ch[SBUS_CHANNELS], uint8_t flags, uint64_t now_us)
{
    if (flags & SBUS_OUT_OFF) {
        s->have = 0; /* silent until channels come again */
        return;
    }
    memcpy(s->ch, ch, sizeof s->ch);
    s->flags = flags;
    if (!s->have)
        s->next_us = now_us; /* the first frame at once */
    s->have = 1;
}

int sbus_out_poll(struct sbus_out *s, uint64_t now_us, uint64_t silent_us, uint8_t out[SBUS_FRAME])
{
    if (!s->period_us || !s->have || now_us < s->next_us)
        return 0;
    uint8_t flags = s->flags;
    if (silent_us)
        flags |= SBUS_FLAG_FRAME_LOST;
    if (silent_us >= SBUS_FAILSAFE_US)
        flags |= SBUS_FLAG_FAILSAFE;
    sbus_encode(s->ch, flags, out);
    s->next_us += s->period_us;
    if (s->next_us <= now_us) /* late: on from now, the missed frames are not sent */
        s->next_us = now_us + s->period_us;
    s->frames++;
    return 1;
}
