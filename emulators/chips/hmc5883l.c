/* HMC5883L: pointer rules, continuous/single/idle timing, RDY and LOCK, gain latency, -4096 on
 * overflow, bias self-test (emulators/hmc5883l.py, docs/sensors.md §4). Times are kept in thirds of a
 * nanosecond, where every output rate's period is a whole number. */
#include <math.h>

#include "chip_internal.h"

void hmc_reset(chip_hmc *h)
{
    memcpy(h->regs, CHIP_HMC_RESET, sizeof h->regs);
    h->pointer = 0;
    h->bitmap = 0;
    h->has_held = false;
    h->gain_effective = CHIP_HMC_GAINS[1];
    h->has_next = true;
    h->anchor_thirds = h->now_thirds;
    h->next_thirds = h->now_thirds + CHIP_HMC_POWER_ON_THIRDS;
    h->start_kind = CHIP_HMC_START_POWER_ON;
    h->anchor_mpu = false;
    h->index = 0;
}

static uint8_t mode(const chip_hmc *h) { return h->regs[HMC_MODE] & 0x03; }

static uint64_t period(const chip_hmc *h) { return CHIP_HMC_PERIOD_THIRDS[(h->regs[HMC_CRA] >> 2) & 0x7]; }

static void place(chip_hmc *h, const uint8_t data[6])
{
    memcpy(h->regs + HMC_DATA, data, 6);
    h->bitmap = 0;
    h->has_held = false;
    h->regs[HMC_STATUS] = 0x01; /* RDY */
}

/* round half away from zero; out of -2048..2047 (or not a number) reads -4096 */
static int16_t quantise(double x)
{
    double r = copysign(floor(fabs(x) + 0.5), x);
    if (!(r >= -2048.0 && r <= 2047.0))
        return CHIP_HMC_OVERFLOW;
    return (int16_t)r;
}

/* the data registers for a field (gauss, sensor x y z) at a gain: X, Z, Y, each big-endian */
static void encode(const double xyz[3], double gain, uint8_t data[6])
{
    const double xzy[3] = { xyz[0], xyz[2], xyz[1] };
    for (int i = 0; i < 3; i++) {
        uint16_t raw = (uint16_t)quantise(xzy[i] * gain);
        data[2 * i] = (uint8_t)(raw >> 8);
        data[2 * i + 1] = (uint8_t)(raw & 0xFF);
    }
}

void hmc_prepare(chip_hmc *h)
{
    double gain = h->gain_effective; /* (read once: the next measurement's, unless one comes first) */
    for (uint16_t k = 0; k < h->q_len; k++) {
        /* volatile: see mpu_prepare (enc_ok is stored after the bytes it vouches for) */
        volatile chip_mag_sample *s = &h->queue[(h->q_head + k) % CHIP_MAG_QUEUE];
        if (s->enc_ok && s->enc_gain == gain)
            continue;
        s->enc_ok = 0;
        double xyz[3] = { s->field[0], s->field[1], s->field[2] };
        uint8_t data[6];
        encode(xyz, gain, data);
        for (int i = 0; i < 6; i++)
            s->enc[i] = data[i];
        s->enc_gain = gain;
        s->enc_ok = 1;
    }
}

/* the held field's bytes at a gain, kept with it: encoded once per gain, however long it is held */
static void keep_encoded(chip_hmc *h, double gain)
{
    encode(h->last.field, gain, h->last.enc);
    h->last.enc_gain = gain;
    h->last.enc_ok = 1;
}

void hmc_prime(chip_hmc *h) { keep_encoded(h, h->gain_effective); }

static void measure(chip_hmc *h)
{
    double gain = h->gain_effective;
    h->gain_effective = CHIP_HMC_GAINS[h->regs[HMC_CRB] >> 5]; /* a new gain counts from the next one */
    uint8_t bias = h->regs[HMC_CRA] & 0x03;
    uint8_t data[6];
    if (bias == 1 || bias == 2) {
        double sign = bias == 1 ? 1.0 : -1.0, xyz[3];
        for (int i = 0; i < 3; i++) /* (CHIP_HMC_BIAS_GA is in X Z Y order, as the registers) */
            xyz[i] = sign * CHIP_HMC_BIAS_GA[i == 0 ? 0 : i == 1 ? 2 : 1];
        encode(xyz, gain, data);
    } else {
        if (!h->last.enc_ok || h->last.enc_gain != gain) /* (else encoded ahead, by hmc_prepare or here) */
            keep_encoded(h, gain);
        memcpy(data, h->last.enc, 6);
    }
    if (h->bitmap && h->bitmap != 0x3F) { /* LOCK: hold the result until the read completes */
        memcpy(h->held, data, 6);
        h->has_held = true;
        return;
    }
    place(h, data);
}

bool hmc_advance(chip_board *b, uint64_t now_thirds, chip_need *need)
{
    chip_hmc *h = &b->hmc;
    if (now_thirds < h->now_thirds)
        return false;
    while (h->has_next && h->next_thirds <= now_thirds) {
        h->now_thirds = h->next_thirds;
        uint8_t bias = h->regs[HMC_CRA] & 0x03;
        if (bias != 1 && bias != 2) { /* the self-test's field is the chip's own: no sample */
            if (!chip_take_mag(h, h->next_thirds / 3)) {
                if (b->demand) {
                    memset(need, 0, sizeof *need);
                    need->chip = CHIP_HMC;
                    need->count = h->index;
                    need->anchor = h->anchor;
                    need->anchor_mpu = h->anchor_mpu;
                    need->hmc_start = h->start_kind;
                    need->anchor_ns = h->anchor_thirds / 3;
                    need->t_ns = h->next_thirds / 3;
                    need->t_thirds = (uint8_t)(h->next_thirds % 3);
                    need->period_ns = period(h) / 3;
                    need->target_ns = now_thirds / 3;
                    return true;
                }
                b->counts[CHIP_COUNT_HMC_UNDERRUNS]++;
            }
        }
        measure(h);
        b->counts[CHIP_COUNT_HMC_MEASUREMENTS]++;
        h->index++;
        if (mode(h) == 0) {
            h->next_thirds += period(h);
        } else { /* single: back to idle */
            h->regs[HMC_MODE] = (uint8_t)((h->regs[HMC_MODE] & ~0x03) | 0x03);
            h->has_next = false;
        }
    }
    h->now_thirds = now_thirds;
    return false;
}

void hmc_start(chip_hmc *h, bool read) { h->first_byte = !read; }

static uint8_t next_pointer(const chip_hmc *h, uint8_t r)
{
    if (r == 8 || (r == 9 && h->status_wraps))
        return 3;
    if (r >= 12)
        return 0;
    return (uint8_t)(r + 1);
}

static void write_reg(chip_hmc *h, uint8_t r, uint8_t value, bool from_aux)
{
    if (r >= CHIP_HMC_REGS || !CHIP_HMC_WRITABLE[r])
        return;
    h->regs[r] = value & CHIP_HMC_STORE_MASK[r];
    if (r != HMC_CRA && r != HMC_MODE)
        return;
    /* measurement configuration changed: LOCK clears, timing restarts */
    h->bitmap = 0;
    h->has_held = false;
    h->regs[HMC_STATUS] &= (uint8_t)~0x02;
    h->anchor++;
    h->anchor_thirds = h->now_thirds;
    h->anchor_mpu = from_aux;
    h->index = 0;
    if (mode(h) == 0) {
        h->next_thirds = h->now_thirds + 2 * period(h);
        h->has_next = true;
        h->start_kind = CHIP_HMC_START_CONTINUOUS;
    } else if (mode(h) == 1) {
        h->next_thirds = h->now_thirds + CHIP_HMC_SINGLE_THIRDS;
        h->has_next = true;
        h->start_kind = CHIP_HMC_START_SINGLE;
        h->regs[HMC_STATUS] &= (uint8_t)~0x01;
    } else {
        h->has_next = false;
    }
}

void hmc_write(chip_hmc *h, uint8_t byte, bool from_aux)
{
    if (h->first_byte) {
        h->pointer = byte;
        h->first_byte = false;
        return;
    }
    write_reg(h, h->pointer, byte, from_aux);
    h->pointer = next_pointer(h, h->pointer);
}

uint8_t hmc_read(chip_hmc *h)
{
    uint8_t r = h->pointer, out;
    if (r == HMC_STATUS) {
        bool locked = h->bitmap != 0 && h->bitmap != 0x3F;
        out = (uint8_t)((h->regs[HMC_STATUS] & 0x01) | (locked ? 0x02 : 0));
    } else {
        out = r < CHIP_HMC_REGS ? h->regs[r] : 0;
    }
    if (r >= HMC_DATA && r < HMC_DATA + 6) {
        h->bitmap |= (uint8_t)(1 << (r - HMC_DATA));
        if (h->bitmap == 0x3F) {
            h->regs[HMC_STATUS] &= (uint8_t)~0x01; /* all six read: RDY clears */
            if (h->has_held) {
                uint8_t held[6];
                memcpy(held, h->held, 6);
                place(h, held);
            }
        }
    }
    h->pointer = next_pointer(h, r);
    return out;
}
