/* The chip core's stand-in: see chip_core.h (a stand-in until branch chip-core is merged). */
#include "chip_core.h"

#include <string.h>

#define MPU_DATA 0x3B
#define MPU_WHO_AM_I 0x75
#define MPU_PWR_MGMT_1 0x6B

static const float ACCEL_LSB_PER_G[4] = { 16384.0f, 8192.0f, 4096.0f, 2048.0f };
static const float GYRO_LSB_PER_DPS[4] = { 131.0f, 65.5f, 32.8f, 16.4f };
static const float HMC_GAIN[8] = { 1370, 1090, 820, 660, 440, 390, 330, 230 };
static const uint32_t HMC_PERIOD_US[8] = { 1333333, 666667, 333333, 133333, 66667, 33333, 13333, 13333 };
static const uint32_t BARO_CONV_NS[5] = { 540000, 1060000, 2080000, 4130000, 8220000 };
static const uint16_t BARO_PROM[8] = { 0x0000, 40127, 36924, 23317, 23282, 33464, 28312, 0x0103 };

static int16_t sat16(float x)
{
    x = x < 0 ? x - 0.5f : x + 0.5f;
    return (int16_t)(x > 32767.0f ? 32767 : x < -32768.0f ? -32768 : (int)x);
}

static void put16(uint8_t *p, int16_t v)
{
    p[0] = (uint8_t)((uint16_t)v >> 8);
    p[1] = (uint8_t)v;
}

static void mpu_reset(struct chip_board *b)
{
    memset(b->mpu, 0, sizeof b->mpu);
    b->mpu[MPU_PWR_MGMT_1] = 0x40;
    b->mpu[MPU_WHO_AM_I] = 0x68;
    memset(b->mpu_img, 0, sizeof b->mpu_img);
}

void chip_board_init(struct chip_board *b, enum chip_topology topology)
{
    memset(b, 0, sizeof *b);
    b->topology = (uint8_t)topology;
    mpu_reset(b);
    static const uint8_t hmc0[13] = { 0x10, 0x20, 0x01, 0, 0, 0, 0, 0, 0, 0, 'H', '4', '3' };
    memcpy(b->hmc, hmc0, sizeof hmc0);
    b->cur = -1;
    b->rng = 1;
}

int chip_mpu_bypass(const struct chip_board *b) { return (b->mpu[0x37] & 0x02) && !(b->mpu[0x6A] & 0x20); }

static int mpu_asleep(const struct chip_board *b) { return (b->mpu[MPU_PWR_MGMT_1] & 0x40) != 0; }

static uint64_t period_ns(const struct chip_board *b, int chip)
{
    if (chip == CHIP_MPU) {
        int dlpf = b->mpu[0x1A] & 7;
        uint64_t base = dlpf == 0 || dlpf == 7 ? 125000u : 1000000u;
        return base * (1u + b->mpu[0x19]);
    }
    return (uint64_t)HMC_PERIOD_US[b->hmc[0] >> 2 & 7] * 1000u;
}

static void encode_image(struct chip_board *b, int chip)
{
    const struct chip_sample *s = &b->queue[chip].cur;
    if (chip == CHIP_MPU) {
        float a = ACCEL_LSB_PER_G[b->mpu[0x1C] >> 3 & 3] / 9.80665f;
        float g = GYRO_LSB_PER_DPS[b->mpu[0x1B] >> 3 & 3] * 57.29578f;
        for (int i = 0; i < 3; i++) {
            put16(b->mpu_img + 2 * i, sat16(s->f[i] * a));
            put16(b->mpu_img + 8 + 2 * i, sat16(s->f[3 + i] * g));
        }
        put16(b->mpu_img + 6, sat16((s->f[6] - 36.53f) * 340.0f));
    } else if (chip == CHIP_HMC) {
        float gain = HMC_GAIN[b->hmc[1] >> 5];
        static const int order[3] = { 0, 2, 1 }; /* X, Z, Y */
        for (int i = 0; i < 3; i++)
            put16(b->hmc_img + 2 * i, sat16(s->f[order[i]] * gain));
        b->hmc[9] |= 0x01;
    }
}

/* The newest queued sample valid by t becomes current: 1 if there was one. */
static int take(struct chip_queue *q, uint64_t t)
{
    int got = 0;
    while (q->n && q->q[q->head].valid_ns <= t) {
        q->cur = q->q[q->head];
        q->head = (q->head + 1) % CHIP_QUEUE;
        q->n--;
        got = 1;
    }
    if (got)
        q->last_taken_valid_ns = q->cur.valid_ns;
    return got;
}

static void baro_finish(struct chip_board *b)
{
    struct chip_queue *q = &b->queue[CHIP_BARO];
    if (!take(q, b->baro_done_ns) && q->have)
        b->counts[CHIP_BARO][CHIP_COUNT_UNDERRUNS]++;
    b->baro_result = b->baro_kind ? q->cur.d2[b->baro_osr] : q->cur.d1[b->baro_osr];
    b->baro_state = 2;
    b->counts[CHIP_BARO][CHIP_COUNT_CONVERSIONS]++;
}

void chip_advance(struct chip_board *b, uint64_t now_ns)
{
    if (now_ns > b->now_ns)
        b->now_ns = now_ns;
    for (int chip = CHIP_MPU; chip <= CHIP_HMC; chip++) {
        struct chip_queue *q = &b->queue[chip];
        if (!q->have || (chip == CHIP_MPU && mpu_asleep(b)))
            continue;
        uint64_t p = period_ns(b, chip);
        while (q->next_instant_ns <= now_ns) {
            if (!take(q, q->next_instant_ns)) {
                if (!q->n) { /* nothing queued: every instant up to now holds the last sample */
                    uint64_t k = (now_ns - q->next_instant_ns) / p + 1;
                    b->counts[chip][CHIP_COUNT_UNDERRUNS] += (uint32_t)k;
                    q->next_instant_ns += k * p;
                    break;
                }
                b->counts[chip][CHIP_COUNT_UNDERRUNS]++;
            }
            encode_image(b, chip);
            q->next_instant_ns += p;
        }
    }
    if (b->baro_state == 1 && now_ns >= b->baro_done_ns)
        baro_finish(b);
}

static int push(struct chip_board *b, int chip, const struct chip_sample *s)
{
    struct chip_queue *q = &b->queue[chip];
    if (q->n == CHIP_QUEUE)
        return -1;
    q->q[(q->head + q->n) % CHIP_QUEUE] = *s;
    q->n++;
    if (!q->have) { /* streaming starts: the first instant is the first sample's */
        q->have = 1;
        q->next_instant_ns = s->valid_ns;
        q->cur = *s;
        encode_image(b, chip);
    }
    return 0;
}

int chip_push_imu(struct chip_board *b, uint64_t valid_ns, const float accel[3], const float gyro[3], float temp_c)
{
    struct chip_sample s;
    memset(&s, 0, sizeof s);
    s.valid_ns = valid_ns;
    for (int i = 0; i < 3; i++) {
        s.f[i] = accel[i];
        s.f[3 + i] = gyro[i];
    }
    s.f[6] = temp_c;
    return push(b, CHIP_MPU, &s);
}

int chip_push_mag(struct chip_board *b, uint64_t valid_ns, const float field[3])
{
    struct chip_sample s;
    memset(&s, 0, sizeof s);
    s.valid_ns = valid_ns;
    for (int i = 0; i < 3; i++)
        s.f[i] = field[i];
    return push(b, CHIP_HMC, &s);
}

int chip_push_baro(struct chip_board *b, uint64_t valid_ns, const uint32_t d1[5], const uint32_t d2[5])
{
    struct chip_sample s;
    memset(&s, 0, sizeof s);
    s.valid_ns = valid_ns;
    memcpy(s.d1, d1, sizeof s.d1);
    memcpy(s.d2, d2, sizeof s.d2);
    struct chip_queue *q = &b->queue[CHIP_BARO];
    if (q->n == CHIP_QUEUE)
        return -1;
    q->q[(q->head + q->n) % CHIP_QUEUE] = s;
    q->n++;
    if (!q->have) {
        q->have = 1;
        q->cur = s;
    }
    return 0;
}

int chip_bus_fault_add(struct chip_board *b, enum chip_id chip, enum chip_fault_kind kind, uint64_t start_ns,
                       uint64_t end_ns, uint64_t period_ns_, float duty)
{
    if ((unsigned)chip >= CHIP_N || b->nfaults[chip] >= CHIP_FAULTS)
        return -1;
    struct chip_fault f = { (uint8_t)kind, start_ns, end_ns, period_ns_, duty };
    b->faults[chip][b->nfaults[chip]++] = f;
    return 0;
}

void chip_bus_fault_seed(struct chip_board *b, uint32_t seed) { b->rng = seed ? seed : 1; }

void chip_bus_fault_clear(struct chip_board *b) { memset(b->nfaults, 0, sizeof b->nfaults); }

static int fault_active(const struct chip_board *b, int chip, int kind, uint64_t t)
{
    for (int i = 0; i < b->nfaults[chip]; i++) {
        const struct chip_fault *f = &b->faults[chip][i];
        if (f->kind != kind || t < f->start_ns || t >= f->end_ns)
            continue;
        if (kind != CHIP_FAULT_INTERMITTENT)
            return 1;
        if (f->period_ns && (double)((t - f->start_ns) % f->period_ns) < f->duty * (double)f->period_ns)
            return 1;
    }
    return 0;
}

static int chip_at(const struct chip_board *b, uint8_t addr)
{
    if (addr == CHIP_MPU_ADDR)
        return CHIP_MPU;
    if (addr == CHIP_BARO_ADDR)
        return CHIP_BARO;
    if (addr == CHIP_HMC_ADDR && (b->topology == CHIP_TOPOLOGY_DIRECT || chip_mpu_bypass(b)))
        return CHIP_HMC;
    return -1;
}

int chip_start(struct chip_board *b, uint64_t t_ns, uint8_t addr, int read)
{
    chip_advance(b, t_ns);
    int chip = chip_at(b, addr);
    b->cur = -1;
    if (chip < 0)
        return 0;
    if (fault_active(b, chip, CHIP_FAULT_OFF, t_ns) || fault_active(b, chip, CHIP_FAULT_INTERMITTENT, t_ns)) {
        b->counts[chip][CHIP_COUNT_NACKS]++;
        return 0;
    }
    b->cur = chip;
    b->reading = read;
    b->first_byte = !read;
    memcpy(b->mpu_latch, b->mpu_img, sizeof b->mpu_latch); /* images swap between transactions only */
    memcpy(b->hmc_latch, b->hmc_img, sizeof b->hmc_latch);
    return 1;
}

static void mpu_write(struct chip_board *b, uint8_t r, uint8_t v)
{
    if ((r >= MPU_DATA && r < MPU_DATA + 14) || r == MPU_WHO_AM_I)
        return; /* read-only */
    if (r == MPU_PWR_MGMT_1 && v & 0x80) {
        mpu_reset(b);
        b->counts[CHIP_MPU][CHIP_COUNT_RESETS]++;
        return;
    }
    int was_asleep = mpu_asleep(b);
    b->mpu[r & 0x7F] = v;
    if (r == MPU_PWR_MGMT_1 && was_asleep && !mpu_asleep(b) && b->queue[CHIP_MPU].have)
        b->queue[CHIP_MPU].next_instant_ns = b->now_ns; /* sampling resumes now */
}

static void baro_command(struct chip_board *b, uint8_t cmd)
{
    b->baro_resp_n = b->baro_resp_at = 0;
    if (cmd == 0x1E) {
        b->baro_state = 0;
    } else if (cmd == 0x00) {
        uint32_t v = b->baro_state == 2 ? b->baro_result : 0;
        b->baro_state = b->baro_state == 2 ? 0 : b->baro_state;
        b->baro_resp[0] = (uint8_t)(v >> 16);
        b->baro_resp[1] = (uint8_t)(v >> 8);
        b->baro_resp[2] = (uint8_t)v;
        b->baro_resp_n = 3;
    } else if (cmd >= 0xA0 && cmd <= 0xAE && !(cmd & 1)) {
        uint16_t w = BARO_PROM[(cmd - 0xA0) / 2];
        b->baro_resp[0] = (uint8_t)(w >> 8);
        b->baro_resp[1] = (uint8_t)w;
        b->baro_resp_n = 2;
    } else if ((cmd & 0xE1) == 0x40 && (cmd >> 1 & 7) <= 4) {
        b->baro_kind = (cmd & 0x10) != 0;
        b->baro_osr = cmd >> 1 & 7;
        b->baro_done_ns = b->now_ns + BARO_CONV_NS[b->baro_osr];
        b->baro_state = 1;
    }
}

int chip_write_byte(struct chip_board *b, uint64_t t_ns, uint8_t byte)
{
    chip_advance(b, t_ns);
    if (b->cur < 0 || b->reading)
        return 0;
    int first = b->first_byte;
    b->first_byte = 0;
    if (b->cur == CHIP_MPU) {
        if (first)
            b->mpu_ptr = byte & 0x7F;
        else {
            mpu_write(b, b->mpu_ptr, byte);
            b->mpu_ptr = b->mpu_ptr >= MPU_WHO_AM_I ? 0 : (uint8_t)(b->mpu_ptr + 1);
        }
    } else if (b->cur == CHIP_HMC) {
        if (first)
            b->hmc_ptr = byte < 13 ? byte : 0;
        else {
            if (b->hmc_ptr <= 2)
                b->hmc[b->hmc_ptr] = byte;
            b->hmc_ptr = b->hmc_ptr >= 12 ? 0 : (uint8_t)(b->hmc_ptr + 1);
        }
    } else if (first) {
        baro_command(b, byte); /* trailing bytes are ignored */
    }
    return 1;
}

static uint8_t garble(struct chip_board *b, uint8_t v, uint64_t t)
{
    if (!fault_active(b, b->cur, CHIP_FAULT_GARBAGE, t))
        return v;
    b->rng = b->rng * 1103515245u + 12345u;
    return (uint8_t)(b->rng >> 16);
}

uint8_t chip_read_byte(struct chip_board *b, uint64_t t_ns)
{
    chip_advance(b, t_ns);
    uint8_t v = 0xFF; /* nobody drives SDA */
    if (b->cur == CHIP_MPU) {
        uint8_t r = b->mpu_ptr;
        v = r >= MPU_DATA && r < MPU_DATA + 14 ? b->mpu_latch[r - MPU_DATA] : b->mpu[r];
        b->mpu_ptr = r >= MPU_WHO_AM_I ? 0 : (uint8_t)(r + 1);
    } else if (b->cur == CHIP_HMC) {
        uint8_t r = b->hmc_ptr;
        v = r >= 3 && r < 9 ? b->hmc_latch[r - 3] : b->hmc[r];
        b->hmc_ptr = r >= 12 ? 0 : (uint8_t)(r + 1);
    } else if (b->cur == CHIP_BARO) {
        v = b->baro_resp_at < b->baro_resp_n ? b->baro_resp[b->baro_resp_at++] : 0;
    }
    return b->cur >= 0 ? garble(b, v, t_ns) : v;
}

void chip_stop(struct chip_board *b, uint64_t t_ns)
{
    chip_advance(b, t_ns);
    b->cur = -1;
}

uint8_t chip_peek(const struct chip_board *b, enum chip_id chip, uint8_t reg)
{
    if (chip == CHIP_MPU)
        return b->mpu[reg & 0x7F];
    if (chip == CHIP_HMC)
        return reg < 13 ? b->hmc[reg] : 0;
    return 0;
}

uint32_t chip_count(const struct chip_board *b, enum chip_id chip, enum chip_counter what)
{
    return (unsigned)chip < CHIP_N && (unsigned)what < CHIP_COUNT_N ? b->counts[chip][what] : 0;
}
