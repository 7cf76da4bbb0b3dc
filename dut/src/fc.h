/*
 * The reference flight controller's algorithms: the seed papers as portable C (no OS, libm only), shared
 * by the platforms in dut/linux (a Linux program) and dut/avr (ATmega2560 firmware).
 * Conventions as docs/design.md section 3: body FRD, earth NED, quaternions scalar-first, Euler ZYX, SI.
 * Everything here is plain computation on structs, so tests link it without any device.
 *
 * Precision: `real` is double, or float with -DFC_SINGLE (the AVR's double is 32 bits anyway, so the
 * host builds the same single-precision arithmetic to test it, with -fsingle-precision-constant so that
 * literals do not widen expressions back to double). On the host <tgmath.h> picks sqrtf for a float and
 * sqrt for a double, so the double build is the very same code as before `real` existed. Clocks stay
 * double (seconds since boot lose milliseconds in a float), and are a platform's business anyway.
 */
#ifndef FC_H
#define FC_H

#include <stddef.h>
#include <stdint.h>
#if defined(__AVR__)
#include <math.h>
#elif defined(FC_GENERIC_MATH)
/* newlib (the STM32 build): its <tgmath.h> wants complex long double functions newlib lacks, so the
   functions the algorithms call pick their float version by C11's _Generic, as <tgmath.h> would (a
   double call on a single-precision FPU is a library routine in software) */
#include <math.h>
#define FC_TG1(fn, x) _Generic((x), float : fn##f, default : fn)(x)
#define FC_TG2(fn, x, y) _Generic((x) + (y), float : fn##f, default : fn)(x, y)
#define sin(x) FC_TG1(sin, x)
#define cos(x) FC_TG1(cos, x)
#define asin(x) FC_TG1(asin, x)
#define sqrt(x) FC_TG1(sqrt, x)
#define fabs(x) FC_TG1(fabs, x)
#define atan2(y, x) FC_TG2(atan2, y, x)
#define pow(x, y) FC_TG2(pow, x, y)
#else
#include <tgmath.h>
#endif

#ifndef M_PI /* (POSIX's, not C's: a strict -std=c11 build lacks it) */
#define M_PI 3.14159265358979323846
#endif

#ifdef FC_SINGLE
typedef float real;
#define FC_TINY 1e-30  /* below this a pivot is singular */
#define FC_EKF_DX 1e-3 /* the EKF's central-difference step: 1e-6 is at float's rounding, 1e-3 is not */
#else
typedef double real;
#define FC_TINY 1e-300
#define FC_EKF_DX 1e-6
#endif

#define FC_G0 9.80665

typedef struct {
    real x, y, z;
} vec3;

vec3 v3(real x, real y, real z);
vec3 v3_add(vec3 a, vec3 b);
vec3 v3_scale(vec3 a, real k);
vec3 v3_cross(vec3 a, vec3 b);
real v3_dot(vec3 a, vec3 b);
real v3_norm(vec3 a);
vec3 v3_unit(vec3 a); /* zero stays zero */

typedef struct {
    real roll, pitch, yaw;
} euler;

/* ---- seed 000: quaternion complementary filter (eqs. 1-5) -------------------------------------- */
typedef struct {
    real q[4];     /* body -> earth */
    vec3 integral; /* sum of e(t) T */
    real kp, ki;
} quat_cf;

void quat_cf_init(quat_cf *f, real kp, real ki);
void quat_cf_set_euler(quat_cf *f, euler e);
/* gyro in rad/s (body), accel any units (body specific force), mag any units (body); T seconds.
   A zero accel or mag vector skips that correction. */
void quat_cf_update(quat_cf *f, vec3 gyro, vec3 accel, vec3 mag, real T);
void picard2(real q[4], vec3 w, real T); /* eq. 3-4, then normalised */
euler quat_to_euler(const real q[4]);    /* eq. 5 */
void euler_to_quat(euler e, real q[4]);

/* ---- seed 002: Mahony filter on the DCM ----------------------------------------------------------- */
typedef struct {
    real R[3][3]; /* body -> earth; rows are r_x, r_y, r_z of eq. 11 */
    vec3 integral;
    real kp, ki;
} mahony_dcm;

void mahony_init(mahony_dcm *f, real kp, real ki);
void mahony_set_euler(mahony_dcm *f, euler e);
void mahony_update(mahony_dcm *f, vec3 gyro, vec3 accel, vec3 mag, real T);
void dcm_orthonormalise(real R[3][3]); /* section 2.3.1 */
euler dcm_to_euler(const real R[3][3]);

/* ---- EKF baseline: state q (4) and gyro bias (3); accel and mag directions measured ---------------- */
typedef struct {
    real x[7];
    real P[7][7];
    real q_gyro, q_bias, r_acc, r_mag;
} ekf7;

void ekf_init(ekf7 *f);
void ekf_set_euler(ekf7 *f, euler e);
void ekf_update(ekf7 *f, vec3 gyro, vec3 accel, vec3 mag, real T);
euler ekf_euler(const ekf7 *f);

/* ---- control (seed 000 eqs. 8-16) ------------------------------------------------------------------ */
typedef struct {
    real kp, ki, kd;
    real sum;  /* sum of e(j) T */
    real prev; /* e(t-1) */
    int started;
    real out_limit; /* |u| <= out_limit (0: none) */
    real sum_limit; /* |ki sum| <= sum_limit (0: none), against wind-up */
    real i_band;    /* > 0: integrate only while |e| <= i_band (conditional integration) */
} pid;

void pid_init(pid *p, real kp, real ki, real kd, real out_limit, real sum_limit);
real pid_step(pid *p, real e, real T); /* eq. 8, position form */
void pid_reset(pid *p);
real clampd(real v, real lo, real hi);

enum mixer_kind { MIXER_PLUS = 0, MIXER_X = 1 };
/* eq. 15 ("+": motor 1 front, 2 left, 3 rear, 4 right) and the X layout of the plant's frame = 1 (1
   front-right, 2 front-left, 3 rear-left, 4 rear-right; control.c); outputs are throttle units (us above
   idle). */
void mix(enum mixer_kind kind, real throttle, real roll, real pitch, real yaw, real out[4]);
real throttle_compensate(real value, real alpha, real beta); /* eq. 16 */

real baro_altitude(real pressure, real start_pressure); /* eq. 6 */

/* Altitude from the barometer fused with vertical acceleration (a second-order complementary filter). */
typedef struct {
    real h, v, k1, k2;
    int started;
} alt_filter;
void alt_filter_init(alt_filter *a, real k1, real k2);
/* acc_up: vertical acceleration (m/s^2, up positive, gravity removed) */
void alt_filter_update(alt_filter *a, real baro_h, real acc_up, real T);

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
real sbus_to_unit(uint16_t raw);          /* 172..1811 -> -1..1 */
real sbus_to_unit_multiwii(uint16_t raw); /* as MultiWii 2.4 reads it: 1024 +- 1000 -> -1..1 */

#endif
