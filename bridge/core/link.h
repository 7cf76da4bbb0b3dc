/* The bridge's side of the link's framing (docs/design.md §8 "Link"): messages of the one table
   (rig/bridge/messages.py, generated into bridge_messages.h) as COBS frames ended by 0x00, each a type
   byte, a sequence byte, the body and a CRC-16/CCITT-FALSE (big-endian). The receiver takes one byte at
   a time (a UART's interrupt hands it bytes), so a frame is never buffered twice; a frame that fails
   its COBS decoding, its CRC, its size or its direction is counted and dropped, never acted on. The
   host's codec (rig/bridge/link.py) follows the same rules; tests hold the two against each other.
   Portable C99: no heap, no OS, no MCU headers. */
#ifndef BRIDGE_LINK_H
#define BRIDGE_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "bridge_messages.h"

/* the longest frame on the wire: COBS adds a byte per 254, the delimiter one more */
#define LINK_WIRE_MAX (BRIDGE_MAX_FRAME + BRIDGE_MAX_FRAME / 254 + 2)

struct link_rx {
    uint8_t buf[LINK_WIRE_MAX];
    size_t n;
    int overflowed; /* the frame being collected was too long: dropped at its delimiter */
    int up;         /* 1: this end receives what a bridge sends (the host's side, tests) */
    uint32_t ok, bad, seq_gaps;
    uint32_t bad_cobs, bad_crc, bad_size, bad_type, bad_direction, bad_overflow;
    int have_seq;
    uint8_t last_seq;
};

uint16_t link_crc16(const uint8_t *p, size_t n);

/* COBS: encode n bytes into out (at least n + n / 254 + 1 bytes), returns the encoded length (no 0x00
   delimiter); decode returns the decoded length, or -1 if the bytes are not COBS. */
size_t link_cobs_encode(const uint8_t *in, size_t n, uint8_t *out);
long link_cobs_decode(const uint8_t *in, size_t n, uint8_t *out);

void link_rx_init(struct link_rx *rx, int up);
/* One received byte: 1 when it completed a good frame (now in *msg), 0 otherwise. */
int link_rx_byte(struct link_rx *rx, uint8_t byte, struct bridge_msg *msg);

/* ``msg`` (id, seq and fields set) as it goes on the wire, delimiter included, into ``out``
   (LINK_WIRE_MAX bytes are enough): its length, 0 for an unknown id. */
size_t link_frame(const struct bridge_msg *msg, uint8_t *out);

#endif
