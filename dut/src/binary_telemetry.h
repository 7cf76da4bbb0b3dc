/* The reference FC's binary telemetry, for both platforms (no stdio, no OS): MSP v1 (MultiWii Serial
   Protocol: the FC answers a request) and MAVLink v2 (the FC streams). Written from the published
   definitions, not generated: MultiWii's MSP (MultiWii 2.4 Protocol.cpp and its wiki's message table)
   and MAVLink's common.xml (each message's fields, wire order and CRC_EXTRA).

   MSP v1 frame: '$' 'M' direction ('<' request, '>' reply, '!' error), size, command, payload (size
   bytes, little-endian fields), checksum (XOR of size, command and payload).
   MAVLink v2 frame: 0xFD, payload length, incompat flags 0, compat flags 0, sequence, system id 1,
   component id 1 (autopilot), message id (24 bits LE), payload (fields largest type first, trailing
   zero bytes dropped), CRC-16/MCRF4XX over everything after 0xFD and then the message's CRC_EXTRA. */
#ifndef BINARY_TELEMETRY_H
#define BINARY_TELEMETRY_H

#include "flight.h"

/* MSP commands answered (MultiWii 2.4's numbers and layouts) */
#define MSP_STATUS 101   /* cycleTime u16 us, i2c_errors u16, sensors u16, flags u32, current set u8 */
#define MSP_RAW_IMU 102  /* acc[3], gyro[3], mag[3]: i16, the board frame (x forward, y left, z up) */
#define MSP_ATTITUDE 108 /* roll, pitch i16 (0.1 deg), heading i16 (deg, -180..180) */
#define MSP_ALTITUDE 109 /* altitude i32 (cm), vario i16 (cm/s) */

/* MAVLink messages sent (common.xml), with their CRC_EXTRA */
#define MAV_HEARTBEAT 0
#define MAV_HEARTBEAT_CRC 50
#define MAV_SCALED_IMU 26
#define MAV_SCALED_IMU_CRC 170
#define MAV_ATTITUDE 30
#define MAV_ATTITUDE_CRC 39
#define MAV_VFR_HUD 74
#define MAV_VFR_HUD_CRC 20

/* custom_mode of the HEARTBEAT: the reference FC's flight modes */
enum { FC_MODE_ANGLE = 0, FC_MODE_ALTHOLD = 1 };

/* What the FC says about itself: a snapshot of one cycle, platform-independent */
typedef struct {
    uint32_t time_ms;    /* since start */
    uint16_t cycle_us;   /* the loop's last cycle */
    uint16_t i2c_errors; /* the platform's count */
    const flight *f;
} tel_snapshot;

/* Room for the largest burst one call writes: the MAVLink stream's four messages, or several MSP replies */
#define TEL_OUT_MAX 160

typedef struct {
    uint8_t state, size, cmd, n, sum; /* the MSP request being read */
    uint8_t seq;                      /* MAVLink's sequence */
    uint32_t next_heartbeat_ms;
} tel_link;

void tel_link_init(tel_link *l);
/* The bytes the FC received on its telemetry port (MSP requests; garbage is skipped, a request with a bad
   checksum ignored): appends each reply to out (at most cap bytes; a reply that does not fit is dropped).
   Returns the bytes written. */
uint16_t tel_msp_serve(tel_link *l, const tel_snapshot *s, const uint8_t *in, uint16_t n, uint8_t *out, uint16_t cap);
/* One MSP reply frame for cmd ('!' error frame, empty, for a command not answered); returns its length
   (at most 6 + 18 bytes). */
uint8_t tel_msp_reply(uint8_t cmd, const tel_snapshot *s, uint8_t *out);
/* The MAVLink stream's next burst: ATTITUDE, SCALED_IMU, VFR_HUD, and a HEARTBEAT once a second. */
uint16_t tel_mavlink_burst(tel_link *l, const tel_snapshot *s, uint8_t *out, uint16_t cap);
/* One MAVLink v2 frame around a payload; returns its length (payload + 12). */
uint8_t tel_mavlink_frame(tel_link *l, uint32_t msgid, uint8_t crc_extra, const uint8_t *payload, uint8_t n,
                          uint8_t *out);

#endif
