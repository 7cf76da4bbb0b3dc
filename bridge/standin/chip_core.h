/* A STAND-IN for the chip core (emulators/chips/chip_core.h, branch chip-core, not merged yet): the API
   the chip core announced, with just enough register behaviour behind it for the bridge's own tests
   (WHO_AM_I and the data registers of the MPU-6050 with its ranges and bypass, the HMC5883L's data and
   identity, the MS5611's commands with its PROM and the host's raw words, sample queues with valid
   times and underruns, register images swapped between transactions only, bus faults). The bridge
   builds against emulators/chips/ instead once chip-core is merged, and this folder goes. It is not
   an emulator: the Python chips (emulators/) and then the chip core are. */
#ifndef CHIP_CORE_H
#define CHIP_CORE_H

#include <stdint.h>

enum chip_topology { CHIP_TOPOLOGY_GY86 = 0, CHIP_TOPOLOGY_DIRECT = 1 };
enum chip_id { CHIP_MPU = 0, CHIP_HMC = 1, CHIP_BARO = 2, CHIP_N = 3 };
enum chip_counter { CHIP_COUNT_UNDERRUNS, CHIP_COUNT_CONVERSIONS, CHIP_COUNT_NACKS, CHIP_COUNT_RESETS, CHIP_COUNT_N };
enum chip_fault_kind { CHIP_FAULT_OFF = 0, CHIP_FAULT_INTERMITTENT = 1, CHIP_FAULT_GARBAGE = 2 };

#define CHIP_MPU_ADDR 0x68
#define CHIP_HMC_ADDR 0x1E
#define CHIP_BARO_ADDR 0x77
#define CHIP_QUEUE 16
#define CHIP_FAULTS 4

struct chip_sample {
    uint64_t valid_ns;
    int32_t v[10]; /* MPU: accel xyz, temp, gyro xyz as in the registers' order (counts); HMC: x z y */
    float f[7];    /* MPU: accel xyz m/s^2, gyro xyz rad/s, temp C; HMC: field xyz gauss */
    uint32_t d1[5], d2[5];
};

struct chip_queue {
    struct chip_sample q[CHIP_QUEUE];
    unsigned head, n;
    int have; /* a sample was ever taken */
    struct chip_sample cur;
    uint64_t next_instant_ns;
    uint64_t last_taken_valid_ns;
};

struct chip_fault {
    uint8_t kind;
    uint64_t start_ns, end_ns, period_ns;
    float duty;
};

struct chip_board {
    uint8_t topology;
    uint8_t mpu[128], hmc[13];
    uint8_t mpu_img[14], hmc_img[6];     /* live data images, updated at sample instants */
    uint8_t mpu_latch[14], hmc_latch[6]; /* what a transaction reads: copied at its START */
    uint8_t mpu_ptr, hmc_ptr;
    int cur;        /* the chip addressed in the transaction (-1 none) */
    int first_byte; /* the next written byte is a pointer / command */
    int reading;
    struct chip_queue queue[CHIP_N];
    /* MS5611 */
    int baro_state; /* 0 idle, 1 converting, 2 done */
    int baro_kind, baro_osr;
    uint64_t baro_done_ns, baro_last_end_ns;
    uint32_t baro_result;
    uint8_t baro_resp[3];
    int baro_resp_n, baro_resp_at;
    struct chip_fault faults[CHIP_N][CHIP_FAULTS];
    int nfaults[CHIP_N];
    uint32_t rng;
    uint32_t counts[CHIP_N][CHIP_COUNT_N];
    uint64_t now_ns;
};

void chip_board_init(struct chip_board *b, enum chip_topology topology);
/* Byte events of the board's bus, at t_ns: START (or repeated START) returns 1 for an ACK. */
int chip_start(struct chip_board *b, uint64_t t_ns, uint8_t addr, int read);
int chip_write_byte(struct chip_board *b, uint64_t t_ns, uint8_t byte);
uint8_t chip_read_byte(struct chip_board *b, uint64_t t_ns);
void chip_stop(struct chip_board *b, uint64_t t_ns);
/* Sample instants up to now_ns: the newest queued sample valid by each instant becomes the chip's
   live image; an instant with none new holds the last and counts an underrun. */
void chip_advance(struct chip_board *b, uint64_t now_ns);
/* 0, or -1 when the queue is full (the sample is dropped). */
int chip_push_imu(struct chip_board *b, uint64_t valid_ns, const float accel[3], const float gyro[3], float temp_c);
int chip_push_mag(struct chip_board *b, uint64_t valid_ns, const float field[3]);
int chip_push_baro(struct chip_board *b, uint64_t valid_ns, const uint32_t d1[5], const uint32_t d2[5]);
/* A bus fault on a chip between start_ns and end_ns: 0, or -1 when the chip has CHIP_FAULTS already. */
int chip_bus_fault_add(struct chip_board *b, enum chip_id chip, enum chip_fault_kind kind, uint64_t start_ns,
                       uint64_t end_ns, uint64_t period_ns, float duty);
void chip_bus_fault_seed(struct chip_board *b, uint32_t seed);
void chip_bus_fault_clear(struct chip_board *b);
uint8_t chip_peek(const struct chip_board *b, enum chip_id chip, uint8_t reg);
int chip_mpu_bypass(const struct chip_board *b);
uint32_t chip_count(const struct chip_board *b, enum chip_id chip, enum chip_counter what);

#endif
