/* The numerics of the IMU's sampling chain, a block of samples per call: the sensor error model of
 * emulators/sensor_models.py (ImuModel) and the MPU-6050's DLPF (_LowPass). Its data registers are the
 * chip core's encoder's (chip_mpu_encode, emulators/chips/mpu6050.c).
 *
 * Why C: the MPU-6050 samples at 1 kHz whatever the flight controller reads, and per sample these few
 * dozen multiply-adds cost far more as Python bytecode than the rest of a lockstep cycle. The Python
 * side keeps the configuration, the random numbers (numpy's generator, handed over in blocks, so the
 * sequence is the generator's own) and the faults; it calls here once per block of samples.
 *
 * The arithmetic is written in the order the Python reference used (left-to-right sums) and built
 * with -ffp-contract=off, so a sample comes out the same to the last bit on any x86-64 or arm64.
 * States are opaque to Python: it allocates rig_*_size() zeroed bytes (a channel then rig_channel_init).
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

/* ---- one triaxial channel: scale/misalignment x mounting, bias, bias random walk, white noise,
 * temperature coefficient (sensor_models.AxisErrors), with the state it carries between samples ---- */

typedef struct {
    double m[9]; /* row-major 3x3 */
    double bias[3];
    double random_walk;      /* units/s/sqrt(Hz) */
    double noise_density;    /* units/sqrt(Hz) */
    double temp_coefficient; /* per degC away from 25 degC */
    double walk[3];
    double last_t;
    int32_t has_last;
    int32_t normals_len, normals_pos;
    const double *normals; /* standard normal draws, owned by the Python side */
} rig_channel;

EXPORT size_t rig_channel_size(void) { return sizeof(rig_channel); }

EXPORT void rig_channel_init(rig_channel *c, const double m[9], const double bias[3], double random_walk,
                             double noise_density, double temp_coefficient)
{
    memset(c, 0, sizeof *c);
    memcpy(c->m, m, sizeof c->m);
    memcpy(c->bias, bias, sizeof c->bias);
    c->random_walk = random_walk;
    c->noise_density = noise_density;
    c->temp_coefficient = temp_coefficient;
}

/* Hands the channel a new buffer of normals (the old one's unread tail must be at its start). */
EXPORT void rig_channel_normals(rig_channel *c, const double *normals, int32_t len)
{
    c->normals = normals;
    c->normals_len = len;
    c->normals_pos = 0;
}

EXPORT int32_t rig_channel_normals_left(const rig_channel *c) { return c->normals_len - c->normals_pos; }

/* The normals one sample draws: 3 for the walk and 3 for the noise, each only when it has a step. */
static int32_t draws_per_sample(const rig_channel *c)
{
    return (c->random_walk != 0.0 ? 3 : 0) + (c->noise_density != 0.0 ? 3 : 0);
}

static void measure_one(rig_channel *c, double t, const double truth[3], double temperature, double out[3])
{
    double d = c->has_last ? t - c->last_t : 0.0;
    double dt = d > 0.0 ? d : 0.0;
    c->last_t = t;
    c->has_last = 1;
    if (c->random_walk != 0.0 && dt > 0.0) {
        double s = c->random_walk * sqrt(dt);
        const double *z = c->normals + c->normals_pos;
        c->normals_pos += 3;
        for (int i = 0; i < 3; i++)
            c->walk[i] = c->walk[i] + s * z[i];
    }
    double k = c->temp_coefficient * (temperature - 25.0);
    for (int i = 0; i < 3; i++) {
        const double *r = c->m + 3 * i;
        out[i] = r[0] * truth[0] + r[1] * truth[1] + r[2] * truth[2] + c->bias[i] + c->walk[i] + k;
    }
    if (c->noise_density != 0.0 && dt > 0.0) {
        double s = c->noise_density / sqrt(2.0 * dt);
        const double *z = c->normals + c->normals_pos;
        c->normals_pos += 3;
        for (int i = 0; i < 3; i++)
            out[i] = out[i] + s * z[i];
    }
}

/* One channel over n samples: truth and out are n rows of 3, temperature n values. Returns 0, or 1 when
 * the channel has too few normals left (nothing is changed then; refill and call again). */
EXPORT int32_t rig_channel_measure(rig_channel *c, int32_t n, const double *t, const double *truth,
                                   const double *temperature, double *out)
{
    if (rig_channel_normals_left(c) < n * draws_per_sample(c))
        return 1;
    for (int32_t i = 0; i < n; i++)
        measure_one(c, t[i], truth + 3 * i, temperature[i], out + 3 * i);
    return 0;
}

/* ImuModel over n samples. rows[i] is the plant-truth row of sample i, cols the columns of fx fy fz
 * p q r temperature in it. out gets n rows of 7: accel xyz, gyro xyz (sensor frame), die temperature.
 * Returns 0, or 1 (accel) / 2 (gyro) when that channel has too few normals left: nothing is changed
 * then, and the caller refills and calls again. */
EXPORT int32_t rig_imu_measure(rig_channel *accel, rig_channel *gyro, int32_t n, const double *t,
                               const double *const *rows, const int32_t cols[7], double die_offset, double *out)
{
    if (rig_channel_normals_left(accel) < n * draws_per_sample(accel))
        return 1;
    if (rig_channel_normals_left(gyro) < n * draws_per_sample(gyro))
        return 2;
    for (int32_t i = 0; i < n; i++) {
        const double *row = rows[i];
        double *o = out + 7 * i;
        double temperature = row[cols[6]] + die_offset;
        double f[3] = { row[cols[0]], row[cols[1]], row[cols[2]] };
        double w[3] = { row[cols[3]], row[cols[4]], row[cols[5]] };
        measure_one(accel, t[i], f, temperature, o);
        measure_one(gyro, t[i], w, temperature, o + 3);
        o[6] = temperature;
    }
    return 0;
}

/* ---- the DLPF: a first-order low-pass plus a pure delay of whole samples (mpu6050._LowPass) ---- */

#define PIPE 64 /* delayed outputs kept: the longest delay, 19 ms at 1 kHz, is 19 samples */

typedef struct {
    double y[3];
    int32_t has_y;
    int32_t head, count;
    double pipe[PIPE][3];
} rig_lowpass;

EXPORT size_t rig_lowpass_size(void) { return sizeof(rig_lowpass); }

EXPORT int32_t rig_lowpass_max_depth(void) { return PIPE - 2; }

/* The exact first-order response to the input held at x over a span whose gain is a. */
static void approach(rig_lowpass *f, const double x[3], double a)
{
    if (!f->has_y) {
        memcpy(f->y, x, sizeof f->y);
        f->has_y = 1;
    }
    for (int i = 0; i < 3; i++)
        f->y[i] = f->y[i] + a * (x[i] - f->y[i]);
}

/* Steps n samples in place: xs[i * stride + 0..2] is replaced by the output of sample i, the filtered
 * value of `depth` samples before (or the oldest there is). depth <= rig_lowpass_max_depth(). */
EXPORT void rig_lowpass_run(rig_lowpass *f, int32_t n, double *xs, int32_t stride, double a, int32_t depth)
{
    for (int32_t i = 0; i < n; i++) {
        double *x = xs + (ptrdiff_t)i * stride;
        approach(f, x, a);
        memcpy(f->pipe[(f->head + f->count) % PIPE], f->y, sizeof f->y);
        f->count++;
        while (f->count > depth + 1) {
            f->head = (f->head + 1) % PIPE;
            f->count--;
        }
        memcpy(x, f->pipe[f->head], sizeof f->y);
    }
}

/* Advances over a whole span of the input held at x in one go; the delay line starts empty again. */
EXPORT void rig_lowpass_catch_up(rig_lowpass *f, const double x[3], double a)
{
    approach(f, x, a);
    f->head = f->count = 0;
}
