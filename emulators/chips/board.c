/* The board: the three chips on one bus (GY-86 or direct topology), their sample queues, bus faults,
 * time, and the bus both as byte-level target events and as whole Linux I2C transfers. */
#include "chip_internal.h"

void chip_board_init(chip_board *b, uint8_t topology)
{
    memset(b, 0, sizeof *b);
    b->topology = topology <= CHIP_TOPOLOGY_MPU_ONLY ? topology : CHIP_TOPOLOGY_GY86;
    b->mpu_addr = CHIP_ADDR_MPU;
    mpu_reset(&b->mpu);
    mpu_prime(&b->mpu);
    hmc_reset(&b->hmc);
    hmc_prime(&b->hmc);
    baro_reset(&b->baro);
}

void chip_board_demand(chip_board *b, bool on) { b->demand = on; }

bool chip_mpu_address(chip_board *b, uint8_t addr)
{
    if (addr != CHIP_ADDR_MPU && addr != CHIP_ADDR_MPU + 1)
        return false;
    b->mpu_addr = addr;
    return true;
}

void chip_ms5611_prom(chip_board *b, const uint16_t words[8]) { memcpy(b->baro.prom, words, sizeof b->baro.prom); }

void chip_ms5611_max_timing(chip_board *b, bool on) { b->baro.max_timing = on; }

void chip_hmc_status_wraps(chip_board *b, bool on) { b->hmc.status_wraps = on; }

/* ---- bus faults ---- */

static bool valid_chip(uint8_t chip) { return chip >= CHIP_MPU && chip <= CHIP_BARO; }

bool chip_bus_fault_add(chip_board *b, uint8_t chip, uint8_t kind, uint64_t start_ns, uint64_t end_ns,
                        uint64_t period_ns, uint64_t duty_ns)
{
    if (!valid_chip(chip) || kind < CHIP_FAULT_OFF || kind > CHIP_FAULT_GARBAGE)
        return false;
    chip_faults *f = &b->faults[chip];
    if (f->n >= CHIP_MAX_FAULTS || (kind == CHIP_FAULT_INTERMITTENT && period_ns == 0))
        return false;
    f->faults[f->n++] = (chip_fault){ kind, start_ns, end_ns, period_ns, duty_ns };
    return true;
}

void chip_bus_fault_seed(chip_board *b, uint8_t chip, uint64_t seed)
{
    if (valid_chip(chip))
        b->faults[chip].rng = seed;
}

void chip_bus_fault_clear(chip_board *b, uint8_t chip)
{
    if (valid_chip(chip))
        b->faults[chip].n = 0;
}

uint64_t chip_splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15u);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
    return z ^ (z >> 31);
}

bool chip_fault_active(const chip_board *b, uint8_t chip, uint8_t kind, uint64_t t_ns)
{
    const chip_faults *f = &b->faults[chip];
    for (uint8_t i = 0; i < f->n; i++)
        if (f->faults[i].kind == kind && f->faults[i].start_ns <= t_ns && t_ns < f->faults[i].end_ns)
            return true;
    return false;
}

/* emulators/faults.py FaultSet.acks: off, or inside the duty part of an intermittent fault's period */
bool chip_answers(const chip_board *b, uint8_t chip, uint64_t t_ns)
{
    if (chip < CHIP_MPU || chip > CHIP_BARO)
        return false;
    const chip_faults *f = &b->faults[chip];
    for (uint8_t i = 0; i < f->n; i++) {
        const chip_fault *x = &f->faults[i];
        if (!(x->start_ns <= t_ns && t_ns < x->end_ns))
            continue;
        if (x->kind == CHIP_FAULT_OFF)
            return false;
        if (x->kind == CHIP_FAULT_INTERMITTENT && (t_ns - x->start_ns) % x->period_ns < x->duty_ns)
            return false;
    }
    return true;
}

/* ---- sample queues ---- */

bool chip_take_imu(chip_mpu *m, uint64_t t_ns)
{
    bool taken = false;
    while (m->q_len && m->queue[m->q_head].valid_ns <= t_ns) {
        m->last = m->queue[m->q_head];
        m->q_head = (uint16_t)((m->q_head + 1) % CHIP_IMU_QUEUE);
        m->q_len--;
        taken = true;
    }
    return taken;
}

bool chip_take_mag(chip_hmc *h, uint64_t t_ns)
{
    bool taken = false;
    while (h->q_len && h->queue[h->q_head].valid_ns <= t_ns) {
        h->last = h->queue[h->q_head];
        h->q_head = (uint16_t)((h->q_head + 1) % CHIP_MAG_QUEUE);
        h->q_len--;
        taken = true;
    }
    return taken;
}

bool chip_take_baro(chip_baro *s, uint64_t t_ns)
{
    bool taken = false;
    while (s->q_len && s->queue[s->q_head].valid_ns <= t_ns) {
        s->last = s->queue[s->q_head];
        s->q_head = (uint16_t)((s->q_head + 1) % CHIP_BARO_QUEUE);
        s->q_len--;
        taken = true;
    }
    return taken;
}

bool chip_push_imu(chip_board *b, uint64_t valid_ns, const double v[7])
{
    bool dropped = false;
    chip_mpu *m = &b->mpu;
    if (m->q_len >= CHIP_IMU_QUEUE) { /* full: the oldest goes (a newer one would supersede it anyway) */
        m->q_head = (uint16_t)((m->q_head + 1) % CHIP_IMU_QUEUE);
        m->q_len--;
        dropped = true;
    }
    chip_imu_sample *s = &m->queue[(m->q_head + m->q_len++) % CHIP_IMU_QUEUE];
    s->valid_ns = valid_ns;
    memcpy(s->v, v, sizeof s->v);
    s->enc_ok = 0;
    return !dropped;
}

bool chip_push_mag(chip_board *b, uint64_t valid_ns, const double field[3])
{
    bool dropped = false;
    chip_hmc *h = &b->hmc;
    if (h->q_len >= CHIP_MAG_QUEUE) { /* full: the oldest goes (a newer one would supersede it anyway) */
        h->q_head = (uint16_t)((h->q_head + 1) % CHIP_MAG_QUEUE);
        h->q_len--;
        dropped = true;
    }
    chip_mag_sample *s = &h->queue[(h->q_head + h->q_len++) % CHIP_MAG_QUEUE];
    s->valid_ns = valid_ns;
    memcpy(s->field, field, sizeof s->field);
    s->enc_ok = 0;
    return !dropped;
}

bool chip_push_baro(chip_board *b, uint64_t valid_ns, uint32_t d1, uint32_t d2)
{
    bool dropped = false;
    chip_baro *s = &b->baro;
    if (s->q_len >= CHIP_BARO_QUEUE) { /* full: the oldest goes (a newer one would supersede it anyway) */
        s->q_head = (uint16_t)((s->q_head + 1) % CHIP_BARO_QUEUE);
        s->q_len--;
        dropped = true;
    }
    s->queue[(s->q_head + s->q_len++) % CHIP_BARO_QUEUE] = (chip_baro_sample){ valid_ns, d1, d2 };
    return !dropped;
}

/* ---- time ---- */

chip_need chip_advance(chip_board *b, uint64_t now_ns)
{
    chip_need need;
    memset(&need, 0, sizeof need);
    if (now_ns < b->now_ns)
        return need;
    if (mpu_advance(b, now_ns, &need) || hmc_advance(b, 3 * now_ns, &need) || baro_advance(b, now_ns, &need))
        return need;
    b->now_ns = now_ns;
    return need;
}

void chip_prepare(chip_board *b)
{
    mpu_prepare(&b->mpu);
    hmc_prepare(&b->hmc);
}

/* ---- bus: byte-level events ---- */

static uint8_t resolve(const chip_board *b, uint8_t addr)
{
    if (addr == b->mpu_addr)
        return CHIP_MPU;
    if (b->topology == CHIP_TOPOLOGY_MPU_ONLY)
        return CHIP_NONE;
    if (addr == CHIP_ADDR_BARO)
        return CHIP_BARO;
    if (addr == CHIP_ADDR_HMC && (b->topology == CHIP_TOPOLOGY_DIRECT || mpu_bypass(&b->mpu)))
        return CHIP_HMC;
    return CHIP_NONE;
}

void chip_stop(chip_board *b)
{
    if (b->current == CHIP_MPU)
        mpu_stop(&b->mpu);
    b->current = CHIP_NONE;
}

static bool start(chip_board *b, uint64_t t_ns, uint8_t addr, bool read)
{
    uint8_t chip = resolve(b, addr);
    b->undo.chip = CHIP_NONE;
    if (chip != CHIP_NONE && !chip_answers(b, chip, t_ns))
        chip = CHIP_NONE;
    if (chip == CHIP_NONE) {
        b->counts[CHIP_COUNT_NACKS]++;
        chip_stop(b);
        return false;
    }
    if (b->current != CHIP_NONE && b->current != chip)
        chip_stop(b);
    b->current = chip;
    if (chip == CHIP_MPU)
        mpu_start(&b->mpu, read);
    else if (chip == CHIP_HMC)
        hmc_start(&b->hmc, read);
    else
        baro_start(&b->baro, read);
    return true;
}

/* Time moves only when a START comes later than the last one: a transfer's repeated STARTs, and one
 * after chip_advance at the same time, do not sample again (the Python bus advances once a transfer). */
bool chip_start(chip_board *b, uint64_t t_ns, uint8_t addr, bool read)
{
    if (t_ns > b->now_ns)
        (void)chip_advance(b, t_ns);
    return start(b, t_ns, addr, read);
}

void chip_write_byte(chip_board *b, uint8_t byte)
{
    if (b->current == CHIP_MPU)
        mpu_write(b, byte);
    else if (b->current == CHIP_HMC)
        hmc_write(&b->hmc, byte, false);
    else if (b->current == CHIP_BARO)
        baro_write(&b->baro, byte);
}

static void remember(chip_board *b, uint8_t chip)
{
    chip_read_undo *u = &b->undo;
    u->chip = chip;
    u->rng = b->faults[chip].rng;
    if (chip == CHIP_MPU) {
        const chip_mpu *m = &b->mpu;
        u->pointer = m->pointer;
        u->mpu_int_status = m->regs[MPU_INT_STATUS];
        u->mpu_fifo_last = m->fifo_last;
        u->mpu_fifo_popped = m->pointer == MPU_FIFO_R_W && m->fifo_len > 0;
        u->mpu_fifo_count_latch = m->fifo_count_latch;
    } else if (chip == CHIP_HMC) {
        const chip_hmc *h = &b->hmc;
        u->pointer = h->pointer;
        u->hmc_status = h->regs[HMC_STATUS];
        memcpy(u->hmc_data, h->regs + HMC_DATA, 6);
        u->hmc_bitmap = h->bitmap;
        u->hmc_has_held = h->has_held;
        memcpy(u->hmc_held, h->held, 6);
    } else {
        u->baro_resp_pos = b->baro.resp_pos;
    }
}

void chip_unread_byte(chip_board *b)
{
    chip_read_undo *u = &b->undo;
    if (u->chip == CHIP_NONE || u->chip != b->current)
        return;
    b->faults[u->chip].rng = u->rng;
    if (u->chip == CHIP_MPU) {
        chip_mpu *m = &b->mpu;
        m->pointer = u->pointer;
        m->regs[MPU_INT_STATUS] = u->mpu_int_status;
        m->fifo_last = u->mpu_fifo_last;
        m->fifo_count_latch = u->mpu_fifo_count_latch;
        if (u->mpu_fifo_popped) { /* the byte is still in the ring: step the head back over it */
            m->fifo_head = (uint16_t)((m->fifo_head + CHIP_FIFO_SIZE - 1) % CHIP_FIFO_SIZE);
            m->fifo_len++;
        }
    } else if (u->chip == CHIP_HMC) {
        chip_hmc *h = &b->hmc;
        h->pointer = u->pointer;
        h->regs[HMC_STATUS] = u->hmc_status;
        memcpy(h->regs + HMC_DATA, u->hmc_data, 6);
        h->bitmap = u->hmc_bitmap;
        h->has_held = u->hmc_has_held;
        memcpy(h->held, u->hmc_held, 6);
    } else {
        b->baro.resp_pos = u->baro_resp_pos;
    }
    u->chip = CHIP_NONE; /* one byte back, not two */
}

uint8_t chip_read_byte(chip_board *b)
{
    uint8_t chip = b->current, v;
    b->undo.chip = CHIP_NONE;
    if (chip != CHIP_NONE)
        remember(b, chip);
    if (chip == CHIP_MPU)
        v = mpu_read(&b->mpu);
    else if (chip == CHIP_HMC)
        v = hmc_read(&b->hmc);
    else if (chip == CHIP_BARO)
        v = baro_read(&b->baro);
    else
        return 0xFF; /* nobody drives the bus: the lines stay high */
    if (chip_fault_active(b, chip, CHIP_FAULT_GARBAGE, b->now_ns))
        v = (uint8_t)(chip_splitmix64(&b->faults[chip].rng) >> 56);
    return v;
}

/* A bridge's target that does not stretch SCL must hold a read's first byte before the address comes:
 * start, read and give back, then put back what start touched (the undo record covers the read). */
bool chip_read_preview(chip_board *b, uint64_t t_ns, uint8_t addr, uint8_t *byte)
{
    uint8_t chip = resolve(b, addr);
    if (chip == CHIP_NONE || !chip_answers(b, chip, t_ns))
        return false;
    uint8_t current = b->current;
    chip_read_undo undo = b->undo;
    bool mpu_first = b->mpu.first_byte, mpu_snap = b->mpu.has_snapshot;
    bool hmc_first = b->hmc.first_byte, baro_first = b->baro.first_byte;
    uint8_t snapshot[sizeof b->mpu.snapshot];
    memcpy(snapshot, b->mpu.snapshot, sizeof snapshot);
    (void)start(b, t_ns, addr, true);
    *byte = chip_read_byte(b);
    chip_unread_byte(b);
    memcpy(b->mpu.snapshot, snapshot, sizeof snapshot);
    b->mpu.first_byte = mpu_first;
    b->mpu.has_snapshot = mpu_snap;
    b->hmc.first_byte = hmc_first;
    b->baro.first_byte = baro_first;
    b->undo = undo;
    b->current = current;
    return true;
}

/* ---- bus: one Linux I2C transfer ---- */

int chip_transfer(chip_board *b, uint64_t t_ns, chip_msg *msgs, uint32_t n, chip_need *need, uint32_t *failed)
{
    chip_need nd = chip_advance(b, t_ns);
    if (nd.chip != CHIP_NONE) {
        if (need)
            *need = nd;
        return CHIP_NEED;
    }
    for (uint32_t i = 0; i < n; i++) {
        chip_msg *msg = &msgs[i];
        bool read = msg->flags & CHIP_MSG_READ;
        if (!start(b, t_ns, msg->addr, read)) {
            if (failed)
                *failed = i;
            return CHIP_NACK;
        }
        if (read && (msg->flags & CHIP_MSG_RECV_LEN)) {
            uint8_t count = chip_read_byte(b);
            msg->buf[0] = count;
            if (count < 1 || count > CHIP_SMBUS_BLOCK_MAX) {
                chip_stop(b);
                if (failed)
                    *failed = i;
                return CHIP_PROTOCOL;
            }
            for (uint8_t j = 0; j < count; j++)
                msg->buf[1 + j] = chip_read_byte(b);
            msg->len = (uint16_t)(1 + count);
        } else if (read) {
            for (uint16_t j = 0; j < msg->len; j++)
                msg->buf[j] = chip_read_byte(b);
        } else {
            for (uint16_t j = 0; j < msg->len; j++)
                chip_write_byte(b, msg->buf[j]);
        }
    }
    chip_stop(b);
    return CHIP_OK;
}

/* ---- looking in ---- */

uint8_t chip_peek(const chip_board *b, uint8_t chip, uint8_t reg)
{
    if (chip == CHIP_MPU && reg < CHIP_MPU_REGS)
        return b->mpu.regs[reg];
    if (chip == CHIP_HMC && reg < CHIP_HMC_REGS)
        return b->hmc.regs[reg];
    return 0;
}

bool chip_mpu_bypass(const chip_board *b) { return mpu_bypass(&b->mpu); }

uint32_t chip_count(const chip_board *b, uint8_t counter) { return counter < CHIP_COUNT_N ? b->counts[counter] : 0; }
