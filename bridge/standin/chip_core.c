/* A STAND-IN for the chip core (branch chip-core: emulators/chips/chip_core.c), implementing the API
   of its header (chip_core.h here is a copy of emulators/chips/chip_core.h at chip-core 693949a) with
   just enough register behaviour for the bridge's own tests: WHO_AM_I and the data registers of the
   MPU-6050 with its ranges, sleep and bypass; the HMC5883L's identity and data; the MS5611's commands,
   PROM and the host's raw words; sample queues with valid times and underruns; a burst read served
   from one sampling instant; bus faults. No FIFO, no aux master, no demand mode. The bridge builds
   against emulators/chips instead once chip-core is merged (Makefile BRIDGE_CHIPS,
   tests/bridge/tools.py CHIPS), and this folder goes. It is not an emulator: emulators/ and the chip
   core are. */
#include "chip_core.h"

#include <string.h>

#define MPU_WHO_AM_I 0x75
#define MPU_PWR_MGMT_1 0x6B
#define HMC_NREGS 13

static const double ACCEL_LSB_PER_G[4] = { 16384.0, 8192.0, 4096.0, 2048.0 };
static const double GYRO_LSB_PER_DPS[4] = { 131.0, 65.5, 32.8, 16.4 };
static const double HMC_GAIN[8] = { 1370, 1090, 820, 660, 440, 390, 330, 230 };
static const uint32_t HMC_PERIOD_US[8] = { 1333333, 666667, 333333, 133333, 66667, 33333, 13333, 13333 };
static const uint32_t BARO_CONV_NS[5] = { 540000, 1060000, 2080000, 4130000, 8220000 };
static const uint16_t BARO_PROM[8] = { 0x0000, 40127, 36924, 23317, 23282, 33464, 28312, 0x0103 };

static int16_t sat16(double x)
{
    x = x < 0 ? x - 0.5 : x + 0.5;
    return (int16_t)(x > 32767.0 ? 32767 : x < -32768.0 ? -32768 : (int)x);
}

static void put16(uint8_t *p, int16_t v)
{
    p[0] = (uint8_t)((uint16_t)v >> 8);
    p[1] = (uint8_t)v;
}

static void mpu_reset(chip_board *b)
{
    memset(b->mpu.regs, 0, sizeof b->mpu.regs);
    b->mpu.regs[MPU_PWR_MGMT_1] = 0x40;
    b->mpu.regs[MPU_WHO_AM_I] = 0x68;
}

void chip_board_init(chip_board *b, uint8_t topology)
{
    memset(b, 0, sizeof *b);
    b->topology = topology;
    mpu_reset(b);
    static const uint8_t hmc0[HMC_NREGS] = { 0x10, 0x20, 0x01, 0, 0, 0, 0, 0, 0, 0, 'H', '4', '3' };
    memcpy(b->hmc.regs, hmc0, sizeof hmc0);
    memcpy(b->baro.prom, BARO_PROM, sizeof BARO_PROM);
    for (int c = 0; c < 4; c++)
        b->faults[c].rng = 0x9E3779B97F4A7C15ull * (uint64_t)(c + 1);
}

void chip_board_demand(chip_board *b, bool on) { b->demand = on; }
void chip_ms5611_prom(chip_board *b, const uint16_t words[8]) { memcpy(b->baro.prom, words, sizeof b->baro.prom); }
void chip_ms5611_max_timing(chip_board *b, bool on) { b->baro.max_timing = on; }
void chip_hmc_status_wraps(chip_board *b, bool on) { b->hmc.status_wraps = on; }

bool chip_mpu_bypass(const chip_board *b) { return (b->mpu.regs[0x37] & 0x02) && !(b->mpu.regs[0x6A] & 0x20); }

static bool mpu_asleep(const chip_board *b) { return (b->mpu.regs[MPU_PWR_MGMT_1] & 0x40) != 0; }

static uint64_t mpu_period(const chip_board *b)
{
    int dlpf = b->mpu.regs[0x1A] & 7;
    uint64_t base = dlpf == 0 || dlpf == 7 ? 125000u : 1000000u;
    return base * (1u + b->mpu.regs[0x19]);
}

static uint64_t hmc_period(const chip_board *b) { return (uint64_t)HMC_PERIOD_US[b->hmc.regs[0] >> 2 & 7] * 1000u; }

/* the newest queued sample valid by t becomes `last`: whether there was one (one macro, three queues) */
#define TAKE(q, len, head, cap, last, t, got)          \
    do {                                               \
        got = false;                                   \
        while ((len) && (q)[(head)].valid_ns <= (t)) { \
            (last) = (q)[(head)];                      \
            (head) = (uint16_t)(((head) + 1) % (cap)); \
            (len)--;                                   \
            got = true;                                \
        }                                              \
    } while (0)

static void baro_finish(chip_board *b)
{
    bool got;
    TAKE(b->baro.queue, b->baro.q_len, b->baro.q_head, CHIP_BARO_QUEUE, b->baro.last, b->baro.t_done_ns, got);
    if (!got && b->baro.corrupt) /* (the stand-in's "a sample was ever pushed") */
        b->counts[CHIP_COUNT_BARO_UNDERRUNS]++;
    b->baro.result = b->baro.kind ? b->baro.last.d2 : b->baro.last.d1;
    b->baro.state = 2;
    b->counts[CHIP_COUNT_BARO_CONVERSIONS]++;
}

chip_need chip_advance(chip_board *b, uint64_t now_ns)
{
    chip_need none;
    memset(&none, 0, sizeof none);
    if (now_ns <= b->now_ns)
        return none;
    b->now_ns = now_ns;
    bool got;
    /* the MPU's sample instants (mpu.anchor: 1 once streaming started, in this stand-in) */
    if (b->mpu.anchor && !mpu_asleep(b)) {
        uint64_t p = mpu_period(b);
        while (b->mpu.next_ns <= now_ns) {
            TAKE(b->mpu.queue, b->mpu.q_len, b->mpu.q_head, CHIP_IMU_QUEUE, b->mpu.last, b->mpu.next_ns, got);
            b->counts[CHIP_COUNT_MPU_SAMPLES]++;
            if (!got) {
                b->counts[CHIP_COUNT_MPU_UNDERRUNS]++;
                if (!b->mpu.q_len) { /* nothing queued: every instant up to now holds the last sample */
                    uint64_t k = (now_ns - b->mpu.next_ns) / p;
                    b->counts[CHIP_COUNT_MPU_UNDERRUNS] += (uint32_t)k;
                    b->counts[CHIP_COUNT_MPU_SAMPLES] += (uint32_t)k;
                    b->mpu.next_ns += k * p;
                }
            }
            b->mpu.next_ns += p;
        }
    }
    /* the HMC's measurements (hmc.has_next: streaming started; next_thirds holds ns here) */
    if (b->hmc.has_next) {
        uint64_t p = hmc_period(b);
        while (b->hmc.next_thirds <= now_ns) {
            TAKE(b->hmc.queue, b->hmc.q_len, b->hmc.q_head, CHIP_MAG_QUEUE, b->hmc.last, b->hmc.next_thirds, got);
            b->counts[CHIP_COUNT_HMC_MEASUREMENTS]++;
            if (!got)
                b->counts[CHIP_COUNT_HMC_UNDERRUNS]++;
            b->hmc.regs[9] |= 0x01;
            b->hmc.next_thirds += p;
        }
    }
    if (b->baro.state == 1 && now_ns >= b->baro.t_done_ns)
        baro_finish(b);
    return none;
}

bool chip_push_imu(chip_board *b, uint64_t valid_ns, const double v[7])
{
    chip_mpu *m = &b->mpu;
    if (m->q_len == CHIP_IMU_QUEUE)
        return false;
    chip_imu_sample s;
    s.valid_ns = valid_ns;
    memcpy(s.v, v, sizeof s.v);
    m->queue[(m->q_head + m->q_len) % CHIP_IMU_QUEUE] = s;
    m->q_len++;
    if (!m->anchor) { /* streaming starts: the first instant is the first sample's */
        m->anchor = 1;
        m->next_ns = valid_ns > b->now_ns ? valid_ns : b->now_ns;
        m->last = s;
    }
    return true;
}

bool chip_push_mag(chip_board *b, uint64_t valid_ns, const double field[3])
{
    chip_hmc *h = &b->hmc;
    if (h->q_len == CHIP_MAG_QUEUE)
        return false;
    chip_mag_sample s;
    s.valid_ns = valid_ns;
    memcpy(s.field, field, sizeof s.field);
    h->queue[(h->q_head + h->q_len) % CHIP_MAG_QUEUE] = s;
    h->q_len++;
    if (!h->has_next) {
        h->has_next = true;
        h->next_thirds = valid_ns > b->now_ns ? valid_ns : b->now_ns;
        h->last = s;
    }
    return true;
}

bool chip_push_baro(chip_board *b, uint64_t valid_ns, uint32_t d1, uint32_t d2)
{
    chip_baro *m = &b->baro;
    if (m->q_len == CHIP_BARO_QUEUE)
        return false;
    chip_baro_sample s = { valid_ns, d1, d2 };
    m->queue[(m->q_head + m->q_len) % CHIP_BARO_QUEUE] = s;
    m->q_len++;
    if (!m->corrupt) {
        m->corrupt = true;
        m->last = s;
    }
    return true;
}

bool chip_bus_fault_add(chip_board *b, uint8_t chip, uint8_t kind, uint64_t start_ns, uint64_t end_ns,
                        uint64_t period_ns, uint64_t duty_ns)
{
    if (chip < CHIP_MPU || chip > CHIP_BARO || b->faults[chip].n >= CHIP_MAX_FAULTS)
        return false;
    chip_fault f = { kind, start_ns, end_ns, period_ns, duty_ns };
    b->faults[chip].faults[b->faults[chip].n++] = f;
    return true;
}

void chip_bus_fault_seed(chip_board *b, uint8_t chip, uint64_t seed)
{
    if (chip >= CHIP_MPU && chip <= CHIP_BARO)
        b->faults[chip].rng = seed;
}

void chip_bus_fault_clear(chip_board *b, uint8_t chip)
{
    if (chip >= CHIP_MPU && chip <= CHIP_BARO)
        b->faults[chip].n = 0;
}

static bool fault_active(const chip_board *b, uint8_t chip, uint8_t kind, uint64_t t)
{
    const chip_faults *fs = &b->faults[chip];
    for (int i = 0; i < fs->n; i++) {
        const chip_fault *f = &fs->faults[i];
        if (f->kind != kind || t < f->start_ns || t >= f->end_ns)
            continue;
        if (kind != CHIP_FAULT_INTERMITTENT)
            return true;
        if (f->period_ns && (t - f->start_ns) % f->period_ns < f->duty_ns)
            return true;
    }
    return false;
}

static uint8_t chip_at(const chip_board *b, uint8_t addr)
{
    if (addr == CHIP_ADDR_MPU)
        return CHIP_MPU;
    if (addr == CHIP_ADDR_BARO)
        return CHIP_BARO;
    if (addr == CHIP_ADDR_HMC && (b->topology == CHIP_TOPOLOGY_DIRECT || chip_mpu_bypass(b)))
        return CHIP_HMC;
    return CHIP_NONE;
}

/* the data registers as of the last instant: what the transaction reads */
static void snapshot(chip_board *b, uint8_t chip)
{
    if (chip == CHIP_MPU) {
        const double *v = b->mpu.last.v;
        double a = ACCEL_LSB_PER_G[b->mpu.regs[0x1C] >> 3 & 3] / 9.80665;
        double g = GYRO_LSB_PER_DPS[b->mpu.regs[0x1B] >> 3 & 3] * 57.29577951308232;
        memset(b->mpu.snapshot, 0, sizeof b->mpu.snapshot);
        if (b->mpu.anchor) {
            for (int i = 0; i < 3; i++) {
                put16(b->mpu.snapshot + 2 * i, sat16(v[i] * a));
                put16(b->mpu.snapshot + 8 + 2 * i, sat16(v[3 + i] * g));
            }
            put16(b->mpu.snapshot + 6, sat16((v[6] - 36.53) * 340.0));
        }
        b->mpu.has_snapshot = true;
    } else if (chip == CHIP_HMC) {
        double gain = HMC_GAIN[b->hmc.regs[1] >> 5];
        static const int order[3] = { 0, 2, 1 }; /* X, Z, Y */
        for (int i = 0; i < 3; i++)
            put16(b->hmc.held + 2 * i, sat16(b->hmc.last.field[order[i]] * gain));
        b->hmc.has_held = true;
    }
}

bool chip_start(chip_board *b, uint64_t t_ns, uint8_t addr, bool read)
{
    chip_advance(b, t_ns);
    uint8_t chip = chip_at(b, addr);
    b->current = CHIP_NONE;
    if (chip == CHIP_NONE || fault_active(b, chip, CHIP_FAULT_OFF, t_ns) ||
        fault_active(b, chip, CHIP_FAULT_INTERMITTENT, t_ns)) {
        b->counts[CHIP_COUNT_NACKS]++;
        return false;
    }
    b->current = chip;
    b->mpu.first_byte = b->hmc.first_byte = b->baro.first_byte = !read;
    snapshot(b, chip); /* a burst is served from one sampling instant */
    return true;
}

static void mpu_write(chip_board *b, uint8_t r, uint8_t v)
{
    if ((r >= CHIP_MPU_DATA_FIRST && r <= 0x48) || r == MPU_WHO_AM_I)
        return; /* read-only */
    if (r == MPU_PWR_MGMT_1 && v & 0x80) {
        mpu_reset(b);
        b->counts[CHIP_COUNT_MPU_RESETS]++;
        return;
    }
    bool was_asleep = mpu_asleep(b);
    b->mpu.regs[r & 0x7F] = v;
    if (r == MPU_PWR_MGMT_1 && was_asleep && !mpu_asleep(b) && b->mpu.anchor)
        b->mpu.next_ns = b->now_ns; /* sampling resumes now */
}

static void baro_command(chip_board *b, uint8_t cmd)
{
    chip_baro *m = &b->baro;
    m->resp_len = m->resp_pos = 0;
    if (cmd == 0x1E) {
        m->state = 0;
    } else if (cmd == 0x00) {
        uint32_t v = m->state == 2 ? m->result : 0;
        m->state = m->state == 2 ? 0 : m->state;
        m->response[0] = (uint8_t)(v >> 16);
        m->response[1] = (uint8_t)(v >> 8);
        m->response[2] = (uint8_t)v;
        m->resp_len = 3;
    } else if (cmd >= 0xA0 && cmd <= 0xAE && !(cmd & 1)) {
        uint16_t w = m->prom[(cmd - 0xA0) / 2];
        m->response[0] = (uint8_t)(w >> 8);
        m->response[1] = (uint8_t)w;
        m->resp_len = 2;
    } else if ((cmd & 0xE1) == 0x40 && (cmd >> 1 & 7) <= 4) {
        m->kind = (cmd & 0x10) != 0;
        m->osr = cmd >> 1 & 7;
        m->t_cmd_ns = b->now_ns;
        m->t_done_ns = b->now_ns + BARO_CONV_NS[m->osr];
        m->state = 1;
    }
}

void chip_write_byte(chip_board *b, uint8_t byte)
{
    if (b->current == CHIP_MPU) {
        if (b->mpu.first_byte)
            b->mpu.pointer = byte & 0x7F;
        else {
            mpu_write(b, b->mpu.pointer, byte);
            b->mpu.pointer = b->mpu.pointer >= MPU_WHO_AM_I ? 0 : (uint8_t)(b->mpu.pointer + 1);
        }
        b->mpu.first_byte = false;
    } else if (b->current == CHIP_HMC) {
        if (b->hmc.first_byte)
            b->hmc.pointer = byte < HMC_NREGS ? byte : 0;
        else {
            if (b->hmc.pointer <= 2)
                b->hmc.regs[b->hmc.pointer] = byte;
            b->hmc.pointer = b->hmc.pointer >= HMC_NREGS - 1 ? 0 : (uint8_t)(b->hmc.pointer + 1);
        }
        b->hmc.first_byte = false;
    } else if (b->current == CHIP_BARO) {
        if (b->baro.first_byte)
            baro_command(b, byte); /* trailing bytes are ignored */
        b->baro.first_byte = false;
    }
}

static uint8_t garble(chip_board *b, uint8_t v)
{
    if (!fault_active(b, b->current, CHIP_FAULT_GARBAGE, b->now_ns))
        return v;
    uint64_t z = (b->faults[b->current].rng += 0x9E3779B97F4A7C15ull); /* splitmix64 */
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return (uint8_t)(z ^ (z >> 31));
}

uint8_t chip_read_byte(chip_board *b)
{
    uint8_t v = 0xFF; /* nobody drives SDA */
    if (b->current == CHIP_MPU) {
        uint8_t r = b->mpu.pointer;
        v = r >= CHIP_MPU_DATA_FIRST && r <= CHIP_MPU_DATA_LAST ? b->mpu.snapshot[r - CHIP_MPU_DATA_FIRST]
                                                                : b->mpu.regs[r];
        b->mpu.pointer = r >= MPU_WHO_AM_I ? 0 : (uint8_t)(r + 1);
    } else if (b->current == CHIP_HMC) {
        uint8_t r = b->hmc.pointer;
        v = r >= 3 && r < 9 ? b->hmc.held[r - 3] : b->hmc.regs[r];
        b->hmc.pointer = r >= HMC_NREGS - 1 ? 0 : (uint8_t)(r + 1);
    } else if (b->current == CHIP_BARO) {
        v = b->baro.resp_pos < b->baro.resp_len ? b->baro.response[b->baro.resp_pos++] : 0;
    }
    return b->current != CHIP_NONE ? garble(b, v) : v;
}

void chip_stop(chip_board *b) { b->current = CHIP_NONE; }

int chip_transfer(chip_board *b, uint64_t t_ns, chip_msg *msgs, uint32_t n, chip_need *need, uint32_t *failed)
{
    memset(need, 0, sizeof *need);
    for (uint32_t i = 0; i < n; i++) {
        chip_msg *m = &msgs[i];
        bool rd = (m->flags & CHIP_MSG_READ) != 0;
        if (!chip_start(b, t_ns, m->addr, rd)) {
            chip_stop(b);
            *failed = i;
            return CHIP_NACK;
        }
        if (!rd) {
            for (uint16_t k = 0; k < m->len; k++)
                chip_write_byte(b, m->buf[k]);
            continue;
        }
        uint16_t len = m->len;
        if (m->flags & CHIP_MSG_RECV_LEN) {
            m->buf[0] = chip_read_byte(b);
            if (m->buf[0] == 0 || m->buf[0] > CHIP_SMBUS_BLOCK_MAX) {
                chip_stop(b);
                *failed = i;
                return CHIP_PROTOCOL;
            }
            m->len = (uint16_t)(1 + m->buf[0]);
            for (uint16_t k = 1; k < m->len; k++)
                m->buf[k] = chip_read_byte(b);
            continue;
        }
        for (uint16_t k = 0; k < len; k++)
            m->buf[k] = chip_read_byte(b);
    }
    chip_stop(b);
    return CHIP_OK;
}

uint8_t chip_peek(const chip_board *b, uint8_t chip, uint8_t reg)
{
    if (chip == CHIP_MPU)
        return b->mpu.regs[reg & 0x7F];
    if (chip == CHIP_HMC)
        return b->hmc.regs[reg & 0x7F];
    return 0;
}

uint32_t chip_count(const chip_board *b, uint8_t counter) { return counter < CHIP_COUNT_N ? b->counts[counter] : 0; }
