/* The link's framing on the bridge: see link.h. */
#include "link.h"

/* CRC-16/CCITT-FALSE four bits at a time: a 16-entry table (each nibble's remainder under 0x1021)
   costs a quarter of the bit loop's instructions for each frame the main loop builds or takes apart */
static const uint16_t CRC_NIBBLE[16] = { 0x0000, 0x1021, 0x2042, 0x3063, 0x4084, 0x50A5, 0x60C6, 0x70E7,
                                         0x8108, 0x9129, 0xA14A, 0xB16B, 0xC18C, 0xD1AD, 0xE1CE, 0xF1EF };

uint16_t link_crc16(const uint8_t *p, size_t n)
{
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i < n; i++) {
        crc = (uint16_t)((crc << 4) ^ CRC_NIBBLE[((crc >> 12) ^ (p[i] >> 4)) & 0xF]);
        crc = (uint16_t)((crc << 4) ^ CRC_NIBBLE[((crc >> 12) ^ (p[i] & 0xF)) & 0xF]);
    }
    return crc;
}

size_t link_cobs_encode(const uint8_t *in, size_t n, uint8_t *out)
{
    size_t code_at = 0, o = 1;
    uint8_t code = 1;
    for (size_t i = 0; i < n; i++) {
        if (in[i] == 0) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
            continue;
        }
        out[o++] = in[i];
        if (++code == 0xFF) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        }
    }
    out[code_at] = code;
    return o;
}

long link_cobs_decode(const uint8_t *in, size_t n, uint8_t *out)
{
    size_t i = 0, o = 0;
    while (i < n) {
        uint8_t code = in[i++];
        if (code == 0 || i + code - 1 > n)
            return -1;
        for (uint8_t k = 1; k < code; k++) {
            if (in[i] == 0)
                return -1;
            out[o++] = in[i++];
        }
        if (code != 0xFF && i < n)
            out[o++] = 0;
    }
    return (long)o;
}

void link_rx_init(struct link_rx *rx, int up)
{
    memset(rx, 0, sizeof *rx);
    rx->up = up;
}

static int reject(struct link_rx *rx, uint32_t *why)
{
    rx->bad++;
    (*why)++;
    return 0;
}

static int frame_done(struct link_rx *rx, struct bridge_msg *msg)
{
    uint8_t raw[BRIDGE_MAX_FRAME + 2];
    if (rx->overflowed)
        return reject(rx, &rx->bad_overflow);
    long n = link_cobs_decode(rx->buf, rx->n, raw);
    if (n < 0)
        return reject(rx, &rx->bad_cobs);
    if (n < 4)
        return reject(rx, &rx->bad_size);
    uint16_t crc = (uint16_t)(raw[n - 2] << 8 | raw[n - 1]);
    if (link_crc16(raw, (size_t)n - 2) != crc)
        return reject(rx, &rx->bad_crc);
    int r = bridge_decode_body(raw[0], raw + 2, (size_t)n - 4, rx->up, msg);
    if (r == -1)
        return reject(rx, &rx->bad_type);
    if (r == -2)
        return reject(rx, &rx->bad_size);
    if (r == -3)
        return reject(rx, &rx->bad_direction);
    msg->seq = raw[1];
    if (rx->have_seq && msg->seq != (uint8_t)(rx->last_seq + 1))
        rx->seq_gaps++;
    rx->have_seq = 1;
    rx->last_seq = msg->seq;
    rx->ok++;
    return 1;
}

int link_rx_byte(struct link_rx *rx, uint8_t byte, struct bridge_msg *msg)
{
    if (byte == 0) {
        int got = rx->n || rx->overflowed ? frame_done(rx, msg) : 0; /* (an idle delimiter is nothing) */
        rx->n = 0;
        rx->overflowed = 0;
        return got;
    }
    if (rx->n >= sizeof rx->buf) {
        rx->overflowed = 1;
        return 0;
    }
    rx->buf[rx->n++] = byte;
    return 0;
}

size_t link_frame(const struct bridge_msg *msg, uint8_t *out)
{
    uint8_t raw[BRIDGE_MAX_FRAME];
    size_t n = bridge_encode_body(msg, raw + 2);
    if (n == 0 && bridge_msg_name(msg->id) == NULL)
        return 0;
    raw[0] = msg->id;
    raw[1] = msg->seq;
    uint16_t crc = link_crc16(raw, n + 2);
    raw[n + 2] = (uint8_t)(crc >> 8);
    raw[n + 3] = (uint8_t)crc;
    size_t w = link_cobs_encode(raw, n + 4, out);
    out[w++] = 0;
    return w;
}
