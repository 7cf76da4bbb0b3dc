/* MPU-6050: register map with reset values and exact read-back, sleep and DEVICE_RESET, FS scaling,
 * sample clock (DLPF_CFG and SMPLRT_DIV), coherent bursts, INT_STATUS, FIFO with latched count,
 * bypass and aux master, self-test (emulators/mpu6050.py, docs/sensors.md §3). The DLPF itself is the
 * host's: its samples arrive filtered; the core encodes them at its sample instants. */
#include <math.h>

#include "chip_internal.h"

void mpu_reset(chip_mpu *m)
{
    memcpy(m->regs, CHIP_MPU_RESET, sizeof m->regs);
    m->fifo_head = m->fifo_len = m->fifo_count_latch = 0;
    m->fifo_last = 0;
    m->has_snapshot = false;
}

static bool asleep(const chip_mpu *m) { return m->regs[MPU_PWR_MGMT_1] & 0x40; }

bool mpu_bypass(const chip_mpu *m) { return (m->regs[MPU_INT_PIN_CFG] & 0x02) && !(m->regs[MPU_USER_CTRL] & 0x20); }

static uint64_t period_ns(const chip_mpu *m)
{
    uint8_t cfg = m->regs[MPU_CONFIG] & 0x07;
    uint64_t base = (cfg == 0 || cfg == 7) ? 125000u : 1000000u; /* 8 kHz or 1 kHz gyro rate */
    return base * (1u + m->regs[MPU_SMPLRT_DIV]);
}

/* ---- the data registers for one sample (docs/sensors.md §3.4, §3.10) ---- */

/* the rounding rule of docs/sensors.md §2: round half away from zero, saturate to int16; NaN reads 0 */
static int16_t quantise(double x)
{
    double r = copysign(floor(fabs(x) + 0.5), x);
    if (!(r == r))
        return 0;
    return r < -32768.0 ? INT16_MIN : r > 32767.0 ? INT16_MAX : (int16_t)r;
}

static void put16(uint8_t *p, int16_t v)
{
    p[0] = (uint8_t)((uint16_t)v >> 8);
    p[1] = (uint8_t)((uint16_t)v & 0xFF);
}

void chip_mpu_encode(uint8_t *regs, const double row[7])
{
    const double rad_to_deg = 180.0 / 3.141592653589793;
    uint8_t *data = regs + CHIP_MPU_DATA_FIRST;
    double lsb_a = CHIP_MPU_ACCEL_LSB[(regs[MPU_ACCEL_CONFIG] >> 3) & 3];
    double lsb_g = CHIP_MPU_GYRO_LSB[(regs[MPU_GYRO_CONFIG] >> 3) & 3];
    uint8_t st_a = regs[MPU_ACCEL_CONFIG] >> 5, st_g = regs[MPU_GYRO_CONFIG] >> 5;
    uint8_t standby = regs[MPU_PWR_MGMT_2];
    for (int i = 0; i < 3; i++) {
        if (!(standby & (0x20 >> i))) {
            double s = st_a & (0x4 >> i) ? CHIP_MPU_ST_ACCEL_G * lsb_a : 0.0;
            put16(data + 2 * i, quantise(row[i] / CHIP_G0 * lsb_a + s));
        }
        if (!(standby & (0x04 >> i))) {
            double sign = i == 1 ? -1.0 : 1.0;
            double s = st_g & (0x4 >> i) ? sign * CHIP_MPU_ST_GYRO_DPS * lsb_g : 0.0;
            put16(data + 8 + 2 * i, quantise(row[3 + i] * rad_to_deg * lsb_g + s));
        }
    }
    if (!(regs[MPU_PWR_MGMT_1] & 0x08))
        put16(data + 6, quantise((row[6] - 36.53) * 340.0));
}

/* ---- aux master and FIFO ---- */

typedef struct {
    uint8_t n, addr, reg, ctrl, ext, len;
} slave;

/* enabled slaves 0..3: read slaves take their LEN bytes of EXT_SENS_DATA consecutively in slave
 * order, write slaves none (the aux master fills this layout and the FIFO copies it) */
static int slaves(const chip_mpu *m, slave out[4])
{
    int k = 0;
    uint8_t ext = MPU_EXT_SENS_DATA_00;
    for (uint8_t n = 0; n < 4; n++) {
        const uint8_t *s = m->regs + MPU_I2C_SLV0_ADDR + 3 * n;
        if (!(s[2] & 0x80))
            continue;
        uint8_t len = 0;
        if (s[0] & 0x80) {
            uint8_t room = (uint8_t)(CHIP_MPU_DATA_LAST + 1 - ext);
            len = (s[2] & 0x0F) < room ? (s[2] & 0x0F) : room;
        }
        out[k++] = (slave){ n, s[0], s[1], s[2], ext, len };
        ext = (uint8_t)(ext + len);
    }
    return k;
}

static void aux_master(chip_board *b, uint64_t t_ns)
{
    chip_mpu *m = &b->mpu;
    slave s[4];
    int k = slaves(m, s);
    uint8_t status = 0;
    for (int i = 0; i < k; i++) {
        if (b->topology != CHIP_TOPOLOGY_GY86 || (s[i].addr & 0x7F) != CHIP_ADDR_HMC) {
            status |= (uint8_t)(1 << s[i].n); /* I2C_SLVn_NACK */
            continue;
        }
        chip_hmc *h = &b->hmc;
        bool garbage = chip_fault_active(b, CHIP_HMC, CHIP_FAULT_GARBAGE, t_ns);
        hmc_start(h, false);
        if (s[i].addr & 0x80) { /* read LEN bytes into EXT_SENS_DATA */
            if (!(s[i].ctrl & 0x20))
                hmc_write(h, s[i].reg, true);
            hmc_start(h, true);
            for (uint8_t j = 0; j < s[i].len; j++) {
                uint8_t v = hmc_read(h);
                m->regs[s[i].ext + j] = garbage ? (uint8_t)(chip_splitmix64(&b->faults[CHIP_HMC].rng) >> 56) : v;
            }
        } else {
            uint8_t d = m->regs[MPU_I2C_SLV0_DO + s[i].n];
            if (s[i].ctrl & 0x20) {
                hmc_write(h, d, true);
            } else {
                hmc_write(h, s[i].reg, true);
                hmc_write(h, d, true);
            }
        }
    }
    m->regs[MPU_I2C_MST_STATUS] = status;
}

static void fifo_put(chip_mpu *m, uint8_t byte)
{
    if (m->fifo_len >= CHIP_FIFO_SIZE) { /* overflow: oldest out, newest kept */
        m->fifo_head = (uint16_t)((m->fifo_head + 1) % CHIP_FIFO_SIZE);
        m->fifo_len--;
        m->regs[MPU_INT_STATUS] |= 0x10;
    }
    m->fifo[(m->fifo_head + m->fifo_len) % CHIP_FIFO_SIZE] = byte;
    m->fifo_len++;
}

static void fifo_record(chip_mpu *m)
{
    uint8_t en = m->regs[MPU_FIFO_EN];
    const uint8_t *r = m->regs;
    if (en & 0x08)
        for (int i = 0; i < 6; i++)
            fifo_put(m, r[CHIP_MPU_DATA_FIRST + i]);
    if (en & 0x80)
        for (int i = 0; i < 2; i++)
            fifo_put(m, r[MPU_TEMP_OUT_H + i]);
    for (int a = 0; a < 3; a++)
        if (en & (0x40 >> a))
            for (int i = 0; i < 2; i++)
                fifo_put(m, r[MPU_GYRO_XOUT_H + 2 * a + i]);
    slave s[4];
    int k = slaves(m, s);
    for (int i = 0; i < k; i++)
        if (s[i].n < 3 && (en & (1 << s[i].n))) /* FIFO_EN has SLV0..SLV2 only */
            for (uint8_t j = 0; j < s[i].len; j++)
                fifo_put(m, r[s[i].ext + j]);
}

/* ---- time ---- */

static void fill_need(chip_need *need, const chip_mpu *m, bool keeps_all, uint32_t count, uint64_t t_ns,
                      uint64_t period, uint64_t target)
{
    memset(need, 0, sizeof *need);
    need->chip = CHIP_MPU;
    need->keeps_all = keeps_all;
    need->count = count;
    need->anchor = m->anchor;
    need->epoch = m->epoch;
    need->t_ns = t_ns;
    need->period_ns = period;
    need->anchor_ns = m->anchor_ns;
    need->target_ns = target;
}

/* Bridge mode, only the last of n instants first, first + p, .. encoded: takes every sample valid by
 * then (the newest is held) and returns how many of the instants had no new one (docs/design.md §8:
 * an underrun at every sample instant without a new sample). A sample is new at the first instant at
 * or after its valid time. */
static uint64_t take_counting(chip_mpu *m, uint64_t first, uint64_t p, uint64_t n)
{
    uint64_t last = first + (n - 1) * p, fresh = 0, prev = 0;
    while (m->q_len && m->queue[m->q_head].valid_ns <= last) {
        uint64_t v = m->queue[m->q_head].valid_ns;
        uint64_t k = v <= first ? 0 : (v - first + p - 1) / p;
        if (fresh == 0 || k > prev) {
            fresh++;
            prev = k;
        }
        chip_take_imu(m, v);
    }
    return n - fresh;
}

/* The encoder needs only the two range registers when no axis is in standby and the temperature is on
 * (then it writes all 14 bytes): only then is a sample encoded ahead. */
static bool encodable_ahead(const uint8_t *regs) { return regs[MPU_PWR_MGMT_2] == 0 && !(regs[MPU_PWR_MGMT_1] & 0x08); }

void mpu_prepare(chip_mpu *m)
{
    uint8_t img[MPU_PWR_MGMT_2 + 1];
    memset(img, 0, sizeof img);
    img[MPU_GYRO_CONFIG] = m->regs[MPU_GYRO_CONFIG]; /* (read once: an interrupt may change them) */
    img[MPU_ACCEL_CONFIG] = m->regs[MPU_ACCEL_CONFIG];
    for (uint16_t k = 0; k < m->q_len; k++) {
        /* volatile: the interrupt that may take this sample meanwhile sees enc_ok set only after the
         * bytes it vouches for (the stores stay in program order) */
        volatile chip_imu_sample *s = &m->queue[(m->q_head + k) % CHIP_IMU_QUEUE];
        if (s->enc_ok && s->enc_cfg[0] == img[MPU_GYRO_CONFIG] && s->enc_cfg[1] == img[MPU_ACCEL_CONFIG])
            continue;
        s->enc_ok = 0;
        double row[7];
        for (int i = 0; i < 7; i++)
            row[i] = s->v[i];
        chip_mpu_encode(img, row);
        for (int i = 0; i < 14; i++)
            s->enc[i] = img[CHIP_MPU_DATA_FIRST + i];
        s->enc_cfg[0] = img[MPU_GYRO_CONFIG];
        s->enc_cfg[1] = img[MPU_ACCEL_CONFIG];
        s->enc_ok = 1;
    }
}

/* the data registers of an image encoded from a sample, kept with it under the image's ranges */
static void keep_encoded(chip_imu_sample *s, const uint8_t *img)
{
    memcpy(s->enc, img + CHIP_MPU_DATA_FIRST, sizeof s->enc);
    s->enc_cfg[0] = img[MPU_GYRO_CONFIG];
    s->enc_cfg[1] = img[MPU_ACCEL_CONFIG];
    s->enc_ok = 1;
}

/* the last sample into the data registers: its bytes encoded ahead when they still hold. Bytes encoded
 * here are kept with it, so a sample held over many instants (the host fell behind, or none came
 * yet) is encoded once per configuration, not at every instant inside a bridge's I2C interrupt. */
static void encode_last(chip_mpu *m)
{
    chip_imu_sample *s = &m->last;
    bool ahead = encodable_ahead(m->regs);
    if (s->enc_ok && ahead && s->enc_cfg[0] == m->regs[MPU_GYRO_CONFIG] && s->enc_cfg[1] == m->regs[MPU_ACCEL_CONFIG]) {
        memcpy(m->regs + CHIP_MPU_DATA_FIRST, s->enc, sizeof s->enc);
        return;
    }
    chip_mpu_encode(m->regs, s->v);
    if (ahead)
        keep_encoded(s, m->regs);
}

void mpu_prime(chip_mpu *m)
{
    uint8_t img[CHIP_MPU_REGS];
    memcpy(img, m->regs, sizeof img);
    chip_mpu_encode(img, m->last.v);
    if (encodable_ahead(img))
        keep_encoded(&m->last, img);
}

bool mpu_advance(chip_board *b, uint64_t now_ns, chip_need *need)
{
    chip_mpu *m = &b->mpu;
    if (now_ns < m->now_ns)
        return false;
    if (asleep(m)) {
        m->now_ns = m->next_ns = now_ns;
        return false;
    }
    uint64_t p = period_ns(m);
    if (m->next_ns < m->now_ns)
        m->next_ns = m->now_ns;
    if (m->next_ns > now_ns) {
        m->now_ns = now_ns;
        return false;
    }
    uint64_t n = (now_ns - m->next_ns) / p + 1;
    bool keeps_all = m->regs[MPU_USER_CTRL] & 0x60;
    if (!keeps_all) { /* only the last instant is ever seen: only it is encoded */
        uint64_t last = m->next_ns + (n - 1) * p;
        if (!b->demand) {
            b->counts[CHIP_COUNT_MPU_UNDERRUNS] += (uint32_t)take_counting(m, m->next_ns, p, n);
        } else if (!chip_take_imu(m, last)) {
            fill_need(need, m, false, (uint32_t)n, m->next_ns, p, now_ns);
            return true;
        }
        encode_last(m);
        m->regs[MPU_INT_STATUS] |= 0x01; /* DATA_RDY, whatever INT_ENABLE says */
        b->counts[CHIP_COUNT_MPU_SAMPLES] += (uint32_t)n;
        m->next_ns = last + p;
    } else {
        while (m->next_ns <= now_ns) {
            uint64_t t = m->next_ns;
            bool aux = m->regs[MPU_USER_CTRL] & 0x20;
            if (aux && hmc_advance(b, 3 * t, need)) /* the magnetometer up to this instant first */
                return true;
            if (!chip_take_imu(m, t)) {
                if (b->demand) {
                    fill_need(need, m, true, (uint32_t)((now_ns - t) / p + 1), t, p, now_ns);
                    return true;
                }
                b->counts[CHIP_COUNT_MPU_UNDERRUNS]++;
            }
            encode_last(m);
            if (aux)
                aux_master(b, t);
            if (m->regs[MPU_USER_CTRL] & 0x40)
                fifo_record(m);
            m->regs[MPU_INT_STATUS] |= 0x01;
            b->counts[CHIP_COUNT_MPU_SAMPLES]++;
            m->next_ns = t + p;
        }
    }
    m->now_ns = now_ns;
    return false;
}

/* ---- bus ---- */

void mpu_start(chip_mpu *m, bool read)
{
    m->first_byte = !read;
    if (read) { /* coherent bursts: the whole read is served from one sampling instant */
        memcpy(m->snapshot, m->regs + CHIP_MPU_DATA_FIRST, sizeof m->snapshot);
        m->has_snapshot = true;
    }
}

void mpu_stop(chip_mpu *m) { m->has_snapshot = false; }

static uint8_t next_reg(uint8_t r) { return r >= MPU_WHO_AM_I ? 0 : (uint8_t)(r + 1); }

static void write_reg(chip_board *b, uint8_t r, uint8_t value)
{
    chip_mpu *m = &b->mpu;
    if (r == MPU_FIFO_R_W) {
        if (m->fifo_len < CHIP_FIFO_SIZE)
            fifo_put(m, value);
        return;
    }
    if (!CHIP_MPU_WRITABLE[r])
        return;
    if (r == MPU_PWR_MGMT_1 && (value & 0x80)) { /* DEVICE_RESET */
        mpu_reset(m);
        m->epoch++;
        b->counts[CHIP_COUNT_MPU_RESETS]++;
        return;
    }
    if (r == MPU_USER_CTRL) {
        if (value & 0x04)
            m->fifo_head = m->fifo_len = 0;
        if (value & 0x01) /* SIG_COND_RESET clears the sensor registers */
            memset(m->regs + CHIP_MPU_DATA_FIRST, 0, MPU_GYRO_XOUT_H + 6 - CHIP_MPU_DATA_FIRST);
    }
    if (r == MPU_PWR_MGMT_1 && asleep(m) && !(value & 0x40)) { /* waking: sampling resumes now */
        m->next_ns = m->anchor_ns = m->now_ns;
        m->anchor++;
    }
    m->regs[r] = value & CHIP_MPU_STORE_MASK[r];
}

void mpu_write(chip_board *b, uint8_t byte)
{
    chip_mpu *m = &b->mpu;
    if (m->first_byte) {
        m->pointer = byte & 0x7F;
        m->first_byte = false;
        return;
    }
    write_reg(b, m->pointer, byte);
    if (m->pointer != MPU_FIFO_R_W)
        m->pointer = next_reg(m->pointer);
}

uint8_t mpu_read(chip_mpu *m)
{
    bool clear_all = m->regs[MPU_INT_PIN_CFG] & 0x10;
    uint8_t r = m->pointer, out;
    if (r == MPU_FIFO_R_W) {
        if (m->fifo_len) {
            m->fifo_last = m->fifo[m->fifo_head];
            m->fifo_head = (uint16_t)((m->fifo_head + 1) % CHIP_FIFO_SIZE);
            m->fifo_len--;
        }
        return m->fifo_last; /* empty: the last byte again */
    }
    if (r == MPU_FIFO_COUNT_H) {
        m->fifo_count_latch = m->fifo_len;
        out = (uint8_t)(m->fifo_count_latch >> 8);
    } else if (r == MPU_FIFO_COUNT_L) {
        out = (uint8_t)(m->fifo_count_latch & 0xFF);
    } else if (r >= CHIP_MPU_DATA_FIRST && r <= CHIP_MPU_DATA_LAST && m->has_snapshot) {
        out = m->snapshot[r - CHIP_MPU_DATA_FIRST];
    } else {
        out = CHIP_MPU_READABLE[r] ? m->regs[r] : 0;
    }
    if (r == MPU_INT_STATUS || clear_all)
        m->regs[MPU_INT_STATUS] = 0;
    m->pointer = next_reg(r);
    return out;
}
