/* MSP v1 replies and a MAVLink v2 stream (binary_telemetry.h), little-endian byte by byte, so the same
   bytes come out of the Linux FC and the AVR. */
#include "binary_telemetry.h"

#include <string.h>

static const real DEG = 180 / M_PI;

static void put16(uint8_t *p, int32_t v)
{
    uint16_t u = (uint16_t)(v < -32768 ? -32768 : v > 32767 ? 32767 : v);
    p[0] = (uint8_t)u;
    p[1] = (uint8_t)(u >> 8);
}

static void put32(uint8_t *p, uint32_t u)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(u >> (8 * i));
}

static void put_float(uint8_t *p, real v)
{
    float f = (float)v;
    uint32_t u;
    memcpy(&u, &f, 4); /* IEEE 754 single on both platforms */
    put32(p, u);
}

static int32_t round_i(real v) { return (int32_t)(v < 0 ? v - 0.5 : v + 0.5); }

/* heading in whole degrees, -180..180 (MSP) or 0..359 (MAVLink) */
static int32_t heading_deg(const flight *f, int signed_range)
{
    int32_t h = round_i(f->att.yaw * DEG);
    while (h > 180)
        h -= 360;
    while (h < -180)
        h += 360;
    return signed_range || h >= 0 ? h : h + 360;
}

void tel_link_init(tel_link *l) { memset(l, 0, sizeof *l); }

/* ---- MSP ----------------------------------------------------------------------------------------- */

static uint8_t msp_payload(uint8_t cmd, const tel_snapshot *s, uint8_t *p)
{
    const flight *f = s->f;
    switch (cmd) {
    case MSP_STATUS: { /* sensors: ACC 1, BARO 2, MAG 4; flags: MultiWii's boxes ARM 0, ANGLE 1, BARO 3 */
        put16(p, s->cycle_us);
        put16(p + 2, s->i2c_errors);
        put16(p + 4, 1 | 2 | 4);
        put32(p + 6, (uint32_t)(f->armed ? 1 : 0) | 2u | (uint32_t)(f->alt_hold ? 8 : 0));
        p[10] = 0;
        return 11;
    }
    case MSP_RAW_IMU: { /* MultiWii's units for a GY-86: acc 512 per g, gyro 4.1 per deg/s, mag the
                           HMC5883L's 1090 per gauss; the board frame: body x, -y, -z */
        const real sign[3] = { 1, -1, -1 };
        const real acc[3] = { f->a.x, f->a.y, f->a.z }, gyro[3] = { f->w.x, f->w.y, f->w.z };
        const real mag[3] = { f->mag.x, f->mag.y, f->mag.z };
        for (int i = 0; i < 3; i++) {
            put16(p + 2 * i, round_i(sign[i] * acc[i] / FC_G0 * 512));
            put16(p + 6 + 2 * i, round_i(sign[i] * gyro[i] * DEG * 4.1));
            put16(p + 12 + 2 * i, round_i(sign[i] * mag[i] * 1090));
        }
        return 18;
    }
    case MSP_ATTITUDE: /* as MultiWii's att.angle: roll right wing down +, pitch nose DOWN + (0.1 deg);
                          heading (deg) */
        put16(p, round_i(f->att.roll * DEG * 10));
        put16(p + 2, round_i(-f->att.pitch * DEG * 10));
        put16(p + 4, heading_deg(f, 1));
        return 6;
    case MSP_ALTITUDE: /* the fused altitude above the start (cm) and its rate, up + (cm/s) */
        put32(p, (uint32_t)round_i(f->altf.h * 100));
        put16(p + 4, round_i(f->altf.v * 100));
        return 6;
    default:
        return 0xFF; /* not answered */
    }
}

uint8_t tel_msp_reply(uint8_t cmd, const tel_snapshot *s, uint8_t *out)
{
    uint8_t n = msp_payload(cmd, s, out + 5);
    int error = n == 0xFF;
    if (error)
        n = 0;
    out[0] = '$';
    out[1] = 'M';
    out[2] = error ? '!' : '>';
    out[3] = n;
    out[4] = cmd;
    uint8_t sum = n ^ cmd;
    for (uint8_t i = 0; i < n; i++)
        sum ^= out[5 + i];
    out[5 + n] = sum;
    return (uint8_t)(6 + n);
}

/* the request parser's states: after '$', 'M', '<', size, command, then the payload and checksum */
enum { MSP_IDLE, MSP_DOLLAR, MSP_M, MSP_SIZE, MSP_CMD, MSP_PAYLOAD };

uint16_t tel_msp_serve(tel_link *l, const tel_snapshot *s, const uint8_t *in, uint16_t n, uint8_t *out, uint16_t cap)
{
    uint16_t written = 0;
    for (uint16_t i = 0; i < n; i++) {
        uint8_t b = in[i];
        switch (l->state) {
        case MSP_IDLE:
            l->state = b == '$' ? MSP_DOLLAR : MSP_IDLE;
            break;
        case MSP_DOLLAR:
            l->state = b == 'M' ? MSP_M : b == '$' ? MSP_DOLLAR : MSP_IDLE;
            break;
        case MSP_M:
            l->state = b == '<' ? MSP_SIZE : b == '$' ? MSP_DOLLAR : MSP_IDLE;
            break;
        case MSP_SIZE:
            l->size = b;
            l->sum = b;
            l->n = 0;
            l->state = MSP_CMD;
            break;
        case MSP_CMD:
            l->cmd = b;
            l->sum ^= b;
            l->state = MSP_PAYLOAD;
            break;
        default: /* the payload (ignored: the commands answered take none), then the checksum */
            if (l->n < l->size) {
                l->sum ^= b;
                l->n++;
                break;
            }
            l->state = MSP_IDLE;
            if (b != l->sum)
                break; /* a damaged request gets no answer, as MultiWii */
            if (written + 6 + 18 <= cap)
                written += tel_msp_reply(l->cmd, s, out + written);
        }
    }
    return written;
}

/* ---- MAVLink ------------------------------------------------------------------------------------- */

/* CRC-16/MCRF4XX (MAVLink's "X.25" accumulate: poly 0x1021 reflected, init 0xFFFF) */
static uint16_t crc_add(uint16_t crc, uint8_t b)
{
    uint8_t t = (uint8_t)(b ^ (uint8_t)crc);
    t ^= (uint8_t)(t << 4);
    return (uint16_t)((crc >> 8) ^ ((uint16_t)t << 8) ^ ((uint16_t)t << 3) ^ (t >> 4));
}

uint8_t tel_mavlink_frame(tel_link *l, uint32_t msgid, uint8_t crc_extra, const uint8_t *payload, uint8_t n,
                          uint8_t *out)
{
    while (n > 1 && payload[n - 1] == 0)
        n--; /* MAVLink 2 sends a payload without its trailing zero bytes (at least one byte stays) */
    const uint8_t header[10] = {
        0xFD, n, 0, 0, l->seq++, 1, 1, (uint8_t)msgid, (uint8_t)(msgid >> 8), (uint8_t)(msgid >> 16)
    };
    memcpy(out, header, 10);
    memcpy(out + 10, payload, n);
    uint16_t crc = 0xFFFF;
    for (uint8_t i = 1; i < 10 + n; i++)
        crc = crc_add(crc, out[i]);
    crc = crc_add(crc, crc_extra);
    out[10 + n] = (uint8_t)crc;
    out[11 + n] = (uint8_t)(crc >> 8);
    return (uint8_t)(12 + n);
}

uint16_t tel_mavlink_burst(tel_link *l, const tel_snapshot *s, uint8_t *out, uint16_t cap)
{
    const flight *f = s->f;
    uint8_t p[28];
    uint16_t n = 0;
    if (cap < 4 * (12 + 28))
        return 0;
    if (s->time_ms >= l->next_heartbeat_ms) { /* type quadrotor (2), autopilot generic (0) */
        l->next_heartbeat_ms = s->time_ms + 1000;
        put32(p, f->alt_hold ? FC_MODE_ALTHOLD : FC_MODE_ANGLE);
        p[4] = 2;
        p[5] = 0;
        p[6] = (uint8_t)(1 | 16 | (f->armed ? 128 : 0)); /* custom mode, stabilize, safety armed */
        p[7] = f->armed ? 4 : 3;                         /* MAV_STATE_ACTIVE, STANDBY */
        p[8] = 3;                                        /* mavlink_version */
        n += tel_mavlink_frame(l, MAV_HEARTBEAT, MAV_HEARTBEAT_CRC, p, 9, out + n);
    }
    put32(p, s->time_ms); /* ATTITUDE: rad and rad/s, body FRD */
    const real att[6] = { f->att.roll, f->att.pitch, f->att.yaw, f->w.x, f->w.y, f->w.z };
    for (int i = 0; i < 6; i++)
        put_float(p + 4 + 4 * i, att[i]);
    n += tel_mavlink_frame(l, MAV_ATTITUDE, MAV_ATTITUDE_CRC, p, 28, out + n);
    put32(p, s->time_ms); /* SCALED_IMU: mG, mrad/s, mgauss, body FRD; temperature (extension) 0 */
    const real imu[9] = { f->a.x / FC_G0 * 1000, f->a.y / FC_G0 * 1000, f->a.z / FC_G0 * 1000,
                          f->w.x * 1000,         f->w.y * 1000,         f->w.z * 1000,
                          f->mag.x * 1000,       f->mag.y * 1000,       f->mag.z * 1000 };
    for (int i = 0; i < 9; i++)
        put16(p + 4 + 2 * i, round_i(imu[i]));
    put16(p + 22, 0);
    n += tel_mavlink_frame(l, MAV_SCALED_IMU, MAV_SCALED_IMU_CRC, p, 24, out + n);
    put_float(p, 0); /* VFR_HUD: airspeed, groundspeed (not measured), alt (m), climb (m/s), heading, throttle % */
    put_float(p + 4, 0);
    put_float(p + 8, f->altf.h);
    put_float(p + 12, f->altf.v);
    put16(p + 16, heading_deg(f, 0));
    put16(p + 18, f->armed ? round_i(f->throttle / 10) : 0);
    n += tel_mavlink_frame(l, MAV_VFR_HUD, MAV_VFR_HUD_CRC, p, 20, out + n);
    return n;
}
