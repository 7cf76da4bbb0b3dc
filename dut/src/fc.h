/*
 * The reference flight controller: the seed papers as a Linux userspace program (libc + libm only).
 * Conventions as docs/design.md section 3: body FRD, earth NED, quaternions scalar-first, Euler ZYX, SI.
 * Everything here is plain computation on structs, so tests link it without any device.
 */
#ifndef FC_H
#define FC_H

#include <stddef.h>
#include <stdint.h>

#define FC_G0 9.80665

typedef struct {
    double x, y, z;
} vec3;

vec3 v3(double x, double y, double z);
vec3 v3_add(vec3 a, vec3 b);
vec3 v3_scale(vec3 a, double k);
vec3 v3_cross(vec3 a, vec3 b);
double v3_dot(vec3 a, vec3 b);
double v3_norm(vec3 a);
vec3 v3_unit(vec3 a); /* zero stays zero */

typedef struct {
    double roll, pitch, yaw;
} euler;

/* ---- seed 000: quaternion complementary filter (eqs. 1-5) -------------------------------------- */
typedef struct {
    double q[4];   /* body -> earth */
    vec3 integral; /* sum of e(t) T */
    double kp, ki;
} quat_cf;

void quat_cf_init(quat_cf *f, double kp, double ki);
void quat_cf_set_euler(quat_cf *f, euler e);
/* gyro in rad/s (body), accel any units (body specific force), mag any units (body); T seconds.
   A zero accel or mag vector skips that correction. */
void quat_cf_update(quat_cf *f, vec3 gyro, vec3 accel, vec3 mag, double T);
void picard2(double q[4], vec3 w, double T); /* eq. 3-4, then normalised */
euler quat_to_euler(const double q[4]);      /* eq. 5 */
void euler_to_quat(euler e, double q[4]);

/* ---- seed 002: Mahony filter on the DCM ----------------------------------------------------------- */
typedef struct {
    double R[3][3]; /* body -> earth; rows are r_x, r_y, r_z of eq. 11 */
    vec3 integral;
    double kp, ki;
} mahony_dcm;

void mahony_init(mahony_dcm *f, double kp, double ki);
void mahony_set_euler(mahony_dcm *f, euler e);
void mahony_update(mahony_dcm *f, vec3 gyro, vec3 accel, vec3 mag, double T);
void dcm_orthonormalise(double R[3][3]); /* section 2.3.1 */
euler dcm_to_euler(const double R[3][3]);

/* ---- EKF baseline: state q (4) and gyro bias (3); accel and mag directions measured ---------------- */
typedef struct {
    double x[7];
    double P[7][7];
    double q_gyro, q_bias, r_acc, r_mag;
} ekf7;

void ekf_init(ekf7 *f);
void ekf_set_euler(ekf7 *f, euler e);
void ekf_update(ekf7 *f, vec3 gyro, vec3 accel, vec3 mag, double T);
euler ekf_euler(const ekf7 *f);

/* ---- control (seed 000 eqs. 8-16) ------------------------------------------------------------------ */
typedef struct {
    double kp, ki, kd;
    double sum;  /* sum of e(j) T */
    double prev; /* e(t-1) */
    int started;
    double out_limit; /* |u| <= out_limit (0: none) */
    double sum_limit; /* |ki sum| <= sum_limit (0: none), against wind-up */
    double i_band;    /* > 0: integrate only while |e| <= i_band (conditional integration) */
} pid;

void pid_init(pid *p, double kp, double ki, double kd, double out_limit, double sum_limit);
double pid_step(pid *p, double e, double T); /* eq. 8, position form */
void pid_reset(pid *p);
double clampd(double v, double lo, double hi);

enum mixer_kind { MIXER_PLUS = 0, MIXER_X = 1 };
/* eq. 15 ("+": motor 1 front, 2 left, 3 rear, 4 right) and the X layout of the plant's frame = 1 (1
   front-right, 2 front-left, 3 rear-left, 4 rear-right; control.c); outputs are throttle units (us above
   idle). */
void mix(enum mixer_kind kind, double throttle, double roll, double pitch, double yaw, double out[4]);
double throttle_compensate(double value, double alpha, double beta); /* eq. 16 */

double baro_altitude(double pressure, double start_pressure); /* eq. 6 */

/* Altitude from the barometer fused with vertical acceleration (a second-order complementary filter). */
typedef struct {
    double h, v, k1, k2;
    int started;
} alt_filter;
void alt_filter_init(alt_filter *a, double k1, double k2);
/* acc_up: vertical acceleration (m/s^2, up positive, gravity removed) */
void alt_filter_update(alt_filter *a, double baro_h, double acc_up, double T);

/* ---- MS5611 datasheet maths -------------------------------------------------------------------------- */
unsigned ms5611_crc4(const uint16_t prom[8]);
/* integer compensation incl. second order; returns P in Pa, TEMP in 0.01 degC */
void ms5611_compensate(const uint16_t prom[8], uint32_t d1, uint32_t d2, int32_t *p, int32_t *temp);
/* The chip's pressure range (10..1200 mbar), in Pa: a compensated value outside it is not a reading */
#define MS5611_P_MIN 1000
#define MS5611_P_MAX 120000

/* How the MS5611's conversion cycle reaches the chip: a combined write-then-read transfer (0 or
   -errno) and a clock (seconds), both the caller's, so the cycle runs on a board and in a test. */
typedef struct {
    int (*xfer)(void *ctx, const uint8_t *w, int wn, uint8_t *r, int rn);
    double (*clock)(void *ctx);
    void *ctx;
} ms5611_bus;
typedef struct {
    uint16_t prom[8];
    uint32_t d1, d2;
    int phase;      /* 0: converting D2 (temperature), 1: converting D1 (pressure) */
    double started; /* clock second the current conversion's command was sent; 0: none yet */
    int have_d2;
    unsigned not_ready; /* ADC reads that found the conversion unfinished (result 0) */
} ms5611_dev;
/* Call each cycle; returns 1 when a new (P [Pa], T [0.01 degC]) pair is ready, 0 when not, -1 on a bus
   error. */
int ms5611_poll(ms5611_dev *d, const ms5611_bus *bus, int32_t *p, int32_t *t);

/* ---- SBUS ------------------------------------------------------------------------------------------ */
#define SBUS_FRAME 25
typedef struct {
    uint16_t ch[16];
    int frame_lost, failsafe;
} sbus_frame;

/* Decodes one 25-byte frame; -1 if header or footer are wrong. */
int sbus_decode(const uint8_t f[SBUS_FRAME], sbus_frame *out);
void sbus_encode(const sbus_frame *in, uint8_t f[SBUS_FRAME]);

/* A byte-stream parser that resynchronises on garbage. */
typedef struct {
    uint8_t buf[SBUS_FRAME];
    size_t n;
    unsigned long frames, errors;
} sbus_parser;
void sbus_parser_init(sbus_parser *p);
/* Feeds bytes; returns 1 and fills *out when the last byte completed a valid frame (the newest wins). */
int sbus_feed(sbus_parser *p, const uint8_t *data, size_t n, sbus_frame *out);
double sbus_to_unit(uint16_t raw); /* 172..1811 -> -1..1 */

#endif
