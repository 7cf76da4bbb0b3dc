/* SBUS out (docs/design.md §8): the sticks the host sends, as 25-byte frames at the configured period,
   byte for byte what emulators/sbus.py's encode() gives: 0x0F, sixteen 11-bit channels packed LSB
   first, a flags byte (bit 0 ch17, bit 1 ch18, bit 2 frame lost, bit 3 failsafe), 0x00. Nothing goes
   out before the host's first channels (a receiver that has not bound); while the host is silent the
   frames carry frame-lost, and failsafe too after SBUS_FAILSAFE_US, as a receiver does when its
   transmitter stops. Portable C99, no heap. */
#ifndef BRIDGE_SBUS_OUT_H
#define BRIDGE_SBUS_OUT_H

#include <stdint.h>

#define SBUS_FRAME 25
#define SBUS_CHANNELS 16
#define SBUS_FLAG_FRAME_LOST 0x04
#define SBUS_FLAG_FAILSAFE 0x08
#define SBUS_FAILSAFE_US 1000000u
#define SBUS_OUT_OFF 0x80 /* the host's flag, never sent: no frames at all (a receiver that stopped output) */

struct sbus_out {
    uint32_t period_us; /* 0: no SBUS */
    int have;           /* channels came */
    uint16_t ch[SBUS_CHANNELS];
    uint8_t flags;
    uint64_t next_us;
    uint32_t frames;
};

/* The frame of 16 channels (masked to 11 bits) and flags. */
void sbus_encode(const uint16_t ch[SBUS_CHANNELS], uint8_t flags, uint8_t out[SBUS_FRAME]);
void sbus_out_init(struct sbus_out *s, uint32_t period_us);
void sbus_out_set(struct sbus_out *s, const uint16_t ch[SBUS_CHANNELS], uint8_t flags, uint64_t now_us);
/* 1 when a frame is due at now_us (written to out); silent_us: how long the host has been silent (0:
   it is not). A late call sends one frame, not the ones it missed. */
int sbus_out_poll(struct sbus_out *s, uint64_t now_us, uint64_t silent_us, uint8_t out[SBUS_FRAME]);

#endif
