/* The chip core: the register behaviour of the GY-86's three chips (MPU-6050, HMC5883L, MS5611) as
 * portable C99, one implementation for the lockstep session (through the rig's extension module) and
 * for the bench bridge's firmware (docs/design.md §8).
 *
 * Portable: no heap, no OS calls, no MCU headers; only <stdint.h>, <stdbool.h>, <string.h> and
 * <math.h>. Time is uint64_t nanoseconds of whoever drives the core (sim time in lockstep, the
 * bridge's clock on a bench). A chip_board is one plain struct (about 6.6 KB), fit for static
 * allocation; nothing in it points outside it.
 *
 * The register maps, reset values, access rules and the constants (FS scales, self-test actuation,
 * HMC gains and rates, MS5611 conversion times) come from the Python tables through a generated
 * header (python -m rig.emulators.chips.gen writes build/gen/chip_registers.h); the Python chips of
 * emulators/ are the reference the core is tested against, byte for byte.
 *
 * Physics comes in as samples, each valid from a time on: chip_push_imu (specific force m/s², rate
 * rad/s, die °C, sensor frame), chip_push_mag (gauss, sensor frame), chip_push_baro (raw D1 and D2,
 * the host's exact inverse of the compensation). At a sample instant a chip takes the newest sample
 * valid at or before it; when none is new it holds the last one and counts an underrun. In demand mode
 * (chip_board_demand, the lockstep session) it stops instead and chip_advance returns what it needs.
 *
 * Bus: either byte-level events as an I2C target sees them (chip_start, chip_write_byte,
 * chip_read_byte, chip_stop: the bridge's interrupts) or one Linux I2C transfer at a time
 * (chip_transfer). A burst read is served from one sampling instant; time moves only at a START.
 */
#ifndef CHIP_CORE_H
#define CHIP_CORE_H

#include <stdbool.h>
#include <stdint.h>

/* what a build may put before every entry point (the rig's library exports them for ctypes) */
#ifndef CHIP_API
#define CHIP_API
#endif

#define CHIP_ADDR_MPU 0x68
#define CHIP_ADDR_HMC 0x1E
#define CHIP_ADDR_BARO 0x77

/* chip_board_init's topology: the HMC5883L behind the MPU-6050 (0x1E only while in bypass, and on the
 * aux master's bus), or all three on the main bus, or the MPU-6050 alone (a GY-521: nothing else on the
 * bus, nothing on its aux bus) */
#define CHIP_TOPOLOGY_GY86 0
#define CHIP_TOPOLOGY_DIRECT 1
#define CHIP_TOPOLOGY_MPU_ONLY 2

/* the chips, as need.chip and the targets of bus faults */
#define CHIP_NONE 0
#define CHIP_MPU 1
#define CHIP_HMC 2
#define CHIP_BARO 3

/* bus fault kinds (emulators/faults.py's BUS_KINDS) */
#define CHIP_FAULT_OFF 1          /* no ACK in [start, end) */
#define CHIP_FAULT_INTERMITTENT 2 /* no ACK for duty of each period, from start */
#define CHIP_FAULT_GARBAGE 3      /* every byte read is random (splitmix64 seeded per chip) */
#define CHIP_MAX_FAULTS 4         /* per chip */

/* chip_count's counters */
#define CHIP_COUNT_MPU_SAMPLES 0      /* sample instants passed (awake) */
#define CHIP_COUNT_MPU_UNDERRUNS 1    /* instants with no new sample: the last one held */
#define CHIP_COUNT_HMC_MEASUREMENTS 2 /* measurements completed */
#define CHIP_COUNT_HMC_UNDERRUNS 3    /* measurements with no new sample */
#define CHIP_COUNT_BARO_CONVERSIONS 4 /* conversions completed */
#define CHIP_COUNT_BARO_UNDERRUNS 5   /* conversions with no new sample */
#define CHIP_COUNT_NACKS 6            /* addresses not acknowledged */
#define CHIP_COUNT_MPU_RESETS 7       /* DEVICE_RESETs */
#define CHIP_COUNT_HMC_ANCHORS 8      /* HMC measurement clock restarts (CRA/MODE writes) */
#define CHIP_COUNT_N 9

/* chip_transfer's results */
#define CHIP_OK 0
#define CHIP_NACK 1     /* message *failed not acknowledged; the messages before it took effect */
#define CHIP_PROTOCOL 2 /* block read of message *failed announced 0 or more than 32 bytes */
#define CHIP_NEED 3     /* demand mode: nothing done; push what *need says and call again */

#define CHIP_MSG_READ 0x01
#define CHIP_MSG_RECV_LEN 0x02 /* SMBus block read: the first byte is the count of the rest (buf >= 33) */
#define CHIP_SMBUS_BLOCK_MAX 32

#define CHIP_IMU_QUEUE 64
#define CHIP_MAG_QUEUE 8
#define CHIP_BARO_QUEUE 8
#define CHIP_FIFO_SIZE 1024
#define CHIP_MPU_REGS 128
#define CHIP_HMC_REGS 128
#define CHIP_MPU_DATA_FIRST 0x3B
#define CHIP_MPU_DATA_LAST 0x60

/* One message of a Linux I2C transfer (struct i2c_msg): a read fills buf with len bytes (a RECV_LEN
 * read sets len to 1 + the count), a write sends buf's len bytes. */
typedef struct {
    uint8_t addr;
    uint8_t flags;
    uint16_t len;
    uint8_t *buf;
} chip_msg;

typedef struct {
    uint64_t valid_ns;
    double v[7]; /* accel xyz (m/s²), gyro xyz (rad/s), die temperature (°C) */
    /* ACCEL_XOUT_H..GYRO_ZOUT_L encoded ahead by chip_prepare (enc_ok) under GYRO_CONFIG/ACCEL_CONFIG
     * = enc_cfg: at its instant the sample is then a copy, not the encoder's double arithmetic */
    uint8_t enc[14];
    uint8_t enc_cfg[2];
    uint8_t enc_ok;
} chip_imu_sample;

typedef struct {
    uint64_t valid_ns;
    double field[3]; /* gauss, sensor frame x y z */
    /* DATA X..Y (X Z Y order) encoded ahead by chip_prepare (enc_ok) under the effective gain enc_gain */
    uint8_t enc[6];
    uint8_t enc_ok;
    double enc_gain;
} chip_mag_sample;

typedef struct {
    uint64_t valid_ns;
    uint32_t d1, d2; /* the raw words a conversion of each kind gives */
} chip_baro_sample;

/* What a chip in demand mode lacks (chip == CHIP_NONE: nothing). The host makes exactly that sample
 * (or block of samples), pushes it and calls again.
 * MPU: samples for `count` instants t_ns, t_ns + period_ns, ... up to target_ns. Without the FIFO or
 *   the aux master (keeps_all 0) only the last instant is encoded, so only its sample is needed;
 *   with them every instant's, in order (push up to CHIP_IMU_QUEUE at a time). `anchor` counts the
 *   sample clock's restarts (wake-ups; the clock restarted at anchor_ns), `epoch` the DEVICE_RESETs.
 * HMC: the field of measurement `count` (0-based) since the measurement clock was anchored at
 *   anchor_ns (`anchor` restarts so far; anchored at one of the MPU's sample instants when
 *   anchor_mpu, by the aux master), due at t_ns (+ t_thirds/3 ns).
 * BARO: D1/D2 for the conversion commanded at anchor_ns with OSR index `osr`, due at t_ns. */
typedef struct {
    uint8_t chip;
    uint8_t keeps_all;
    uint8_t anchor_mpu;
    uint8_t osr;
    uint8_t t_thirds;
    uint8_t hmc_start; /* HMC: what the anchor was: CHIP_HMC_START_POWER_ON, _CONTINUOUS or _SINGLE */
    uint32_t count;
    uint32_t anchor;
    uint32_t epoch;
    uint64_t t_ns;
    uint64_t period_ns;
    uint64_t anchor_ns;
    uint64_t target_ns;
} chip_need;

/* need.hmc_start: the first measurement after an anchor is due POWER_ON_S after power-on, two periods
 * after a continuous-mode start, SINGLE_S after a single-measurement start; then one period apart */
#define CHIP_HMC_START_POWER_ON 0
#define CHIP_HMC_START_CONTINUOUS 1
#define CHIP_HMC_START_SINGLE 2

typedef struct {
    uint8_t kind;
    uint64_t start_ns, end_ns, period_ns, duty_ns;
} chip_fault;

typedef struct {
    chip_fault faults[CHIP_MAX_FAULTS];
    uint8_t n;
    uint64_t rng; /* splitmix64 state of the garbage bytes */
} chip_faults;

typedef struct {
    uint8_t regs[CHIP_MPU_REGS];
    uint8_t snapshot[CHIP_MPU_DATA_LAST + 1 - CHIP_MPU_DATA_FIRST];
    bool has_snapshot;
    bool first_byte; /* the next byte written is the register pointer */
    uint8_t pointer;
    uint8_t fifo[CHIP_FIFO_SIZE];
    uint16_t fifo_head, fifo_len, fifo_count_latch;
    uint8_t fifo_last;
    uint64_t now_ns, next_ns, anchor_ns;
    uint32_t anchor, epoch;
    chip_imu_sample last; /* the sample last taken (held on an underrun) */
    chip_imu_sample queue[CHIP_IMU_QUEUE];
    uint16_t q_head, q_len;
} chip_mpu;

typedef struct {
    uint8_t regs[CHIP_HMC_REGS];
    uint8_t pointer;
    bool first_byte;
    bool status_wraps;
    bool has_next;
    uint64_t now_thirds, next_thirds, anchor_thirds; /* times in thirds of a ns: the rates are exact */
    bool anchor_mpu;
    uint8_t start_kind;
    uint32_t anchor, index; /* restarts so far; the next measurement's index since the anchor */
    uint16_t gain_effective;
    uint8_t bitmap;
    bool has_held;
    uint8_t held[6];
    chip_mag_sample last;
    chip_mag_sample queue[CHIP_MAG_QUEUE];
    uint16_t q_head, q_len;
} chip_hmc;

typedef struct {
    uint16_t prom[8];
    bool max_timing;
    bool first_byte;
    uint8_t state; /* 0 idle, 1 converting, 2 done */
    uint8_t kind;  /* 0 D1, 1 D2 */
    uint8_t osr;
    bool corrupt;
    uint32_t result;
    uint8_t response[3];
    uint8_t resp_len, resp_pos;
    uint64_t now_ns, t_cmd_ns, t_done_ns;
    chip_baro_sample last;
    chip_baro_sample queue[CHIP_BARO_QUEUE];
    uint16_t q_head, q_len;
} chip_baro;

/* What the last chip_read_byte changed, so chip_unread_byte can give that byte back: an I2C target
 * peripheral that loads the next byte while the master still clocks the one before (the STM32's
 * TXDR) takes one byte more than a master that NACKs reads. Everything a read can change is here. */
typedef struct {
    uint8_t chip; /* CHIP_NONE: nothing to give back */
    uint64_t rng; /* the garbage fault's generator */
    uint8_t pointer;
    uint8_t mpu_int_status, mpu_fifo_last;
    bool mpu_fifo_popped;
    uint16_t mpu_fifo_count_latch;
    uint8_t hmc_status, hmc_data[6], hmc_bitmap, hmc_held[6];
    bool hmc_has_held;
    uint8_t baro_resp_pos;
} chip_read_undo;

typedef struct {
    uint8_t topology;
    uint8_t mpu_addr; /* CHIP_ADDR_MPU, or 0x69 with AD0 high */
    bool demand;
    uint8_t current; /* the chip addressed since the last START (CHIP_NONE: none) */
    uint64_t now_ns;
    chip_mpu mpu;
    chip_hmc hmc;
    chip_baro baro;
    chip_faults faults[4]; /* by chip (index 0 unused) */
    uint32_t counts[CHIP_COUNT_N];
    chip_read_undo undo;
} chip_board;

/* ---- set-up ---- */
CHIP_API void chip_board_init(chip_board *b, uint8_t topology); /* power-on state at time 0, demand off */
CHIP_API void chip_board_demand(chip_board *b, bool on);
CHIP_API bool chip_mpu_address(chip_board *b, uint8_t addr); /* 0x68, or 0x69 (AD0 high); false otherwise */
CHIP_API void chip_ms5611_prom(chip_board *b, const uint16_t words[8]);
CHIP_API void chip_ms5611_max_timing(chip_board *b, bool on); /* the datasheet's maximum conversion times */
CHIP_API void chip_hmc_status_wraps(chip_board *b, bool on);  /* pointer after STATUS (0x09) goes to 0x03 */
CHIP_API bool chip_bus_fault_add(chip_board *b, uint8_t chip, uint8_t kind, uint64_t start_ns, uint64_t end_ns,
                                 uint64_t period_ns, uint64_t duty_ns); /* false when the chip has no room */
CHIP_API void chip_bus_fault_seed(chip_board *b, uint8_t chip, uint64_t seed);
CHIP_API void chip_bus_fault_clear(chip_board *b, uint8_t chip);
/* no bus fault keeps the chip silent at t_ns (off, or the silent part of an intermittent period): a
 * bridge's target hardware stops acknowledging its address while it is */
CHIP_API bool chip_answers(const chip_board *b, uint8_t chip, uint64_t t_ns);

/* ---- samples ---- always queued; false: the queue was full and its oldest sample was dropped to make
 * room (a streaming host that runs ahead while a chip takes none, asleep or idle, loses nothing: a chip
 * reads only the newest sample valid at its instant) */
CHIP_API bool chip_push_imu(chip_board *b, uint64_t valid_ns, const double v[7]);
CHIP_API bool chip_push_mag(chip_board *b, uint64_t valid_ns, const double field[3]);
CHIP_API bool chip_push_baro(chip_board *b, uint64_t valid_ns, uint32_t d1, uint32_t d2);

/* ---- time ---- Runs every chip up to now_ns (sample instants, aux master, FIFO, measurements,
 * conversions); an earlier time does nothing. Returns need.chip == CHIP_NONE when done; in demand
 * mode it may stop before an instant it lacks a sample for and return what it needs. */
CHIP_API chip_need chip_advance(chip_board *b, uint64_t now_ns);

/* ---- ahead of time ---- Encodes the queued IMU samples under the MPU's present configuration (and
 * the magnetometer's under its effective gain), so that chip_advance (in a bridge: inside the I2C
 * interrupt, or the masked poll) copies the bytes instead of encoding them: a
 * port calls it from its main loop with interrupts enabled. It may be interrupted anywhere by
 * chip_start/chip_advance (a sample taken meanwhile is encoded there, as without it); a configuration
 * changed since, or an axis in standby, is encoded at the instant too. Optional: the bytes are the same. */
CHIP_API void chip_prepare(chip_board *b);

/* ---- bus: byte-level events ---- chip_start advances to t_ns when that is later than the last time
 * (a repeated START at the same time does not sample again), stops the chip addressed before if
 * another one is, and returns whether addr acknowledged. Bytes go to the chip of the last
 * acknowledged START; chip_stop ends the transfer. */
CHIP_API bool chip_start(chip_board *b, uint64_t t_ns, uint8_t addr, bool read);
CHIP_API void chip_write_byte(chip_board *b, uint8_t byte);
CHIP_API uint8_t chip_read_byte(chip_board *b);
CHIP_API void chip_unread_byte(chip_board *b); /* the last byte read was never sent: as if not read */
CHIP_API void chip_stop(chip_board *b);
/* The first byte a read of addr would give if it started now (time does not move: the board's state
 * as it is, t_ns only for the bus faults' windows), with nothing changed, the transfer under way
 * included; false when addr would not acknowledge. A bridge target without clock stretching loads it
 * before the address comes. */
CHIP_API bool chip_read_preview(chip_board *b, uint64_t t_ns, uint8_t addr, uint8_t *byte);

/* ---- bus: one Linux I2C transfer at t_ns ---- CHIP_OK, CHIP_NACK / CHIP_PROTOCOL (message index in
 * *failed), or CHIP_NEED (demand mode; nothing done, *need filled). */
CHIP_API int chip_transfer(chip_board *b, uint64_t t_ns, chip_msg *msgs, uint32_t n, chip_need *need, uint32_t *failed);

/* ---- the MPU-6050's encoder ---- The data registers ACCEL_XOUT_H..GYRO_ZOUT_L (regs[0x3B..0x48]) for
 * one sample row (accel xyz m/s², gyro xyz rad/s, die °C, sensor frame) under the configuration in
 * regs (ACCEL_CONFIG and GYRO_CONFIG: full scale and self-test; PWR_MGMT_2: an axis in standby keeps its
 * bytes; PWR_MGMT_1.TEMP_DIS: so does the temperature). regs is an MPU register image up to PWR_MGMT_2
 * (0x6C) at least. The chips encode every sample with it; the Python chip (emulators/mpu6050.py) too. */
CHIP_API void chip_mpu_encode(uint8_t *regs, const double row[7]);

/* ---- looking in ---- */
CHIP_API uint8_t chip_peek(const chip_board *b, uint8_t chip, uint8_t reg); /* a register as stored, no side effect */
CHIP_API bool chip_mpu_bypass(const chip_board *b);                         /* 0x1E reachable on the main bus (GY-86) */
CHIP_API uint32_t chip_count(const chip_board *b, uint8_t counter);

#endif
