/* Algorithm tests of the reference FC against independent truth. Prints "ok <name>" per check and
   "FAIL <name>: ..." with a non-zero exit on the first failure; pytest runs this (tests/dut/).
   Built twice: double (build/dut/test_fc) and single precision (test_fc32, -DFC_SINGLE, as the AVR
   computes). The truth stays in double; the algorithms get `real`. Where float's rounding sets the
   bar, PREC(double bound, float bound) says so: each float bound is the measured float error with a
   margin, and still far below what a wrong algorithm gives. */
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fc.h"
#include "flight.h"

#define DEG (M_PI / 180.0)
#ifdef FC_SINGLE
#define PREC(d, f) (f)
#else
#define PREC(d, f) (d)
#endif
static int failures;

static void check(int ok, const char *name, const char *fmt, double a, double b)
{
    if (ok) {
        printf("ok %s\n", name);
        return;
    }
    printf("FAIL %s: ", name);
    printf(fmt, a, b);
    printf("\n");
    failures++;
}

/* the rotation angle between two unit quaternions, from conj(a) b's vector part (acos of the dot
   product rounds small angles to zero, in float always) */
static double angle_between(const real a[4], const double b[4])
{
    double w = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    double x = a[0] * b[1] - a[1] * b[0] - a[2] * b[3] + a[3] * b[2];
    double y = a[0] * b[2] + a[1] * b[3] - a[2] * b[0] - a[3] * b[1];
    double z = a[0] * b[3] - a[1] * b[2] + a[2] * b[1] - a[3] * b[0];
    return 2 * atan2(sqrt(x * x + y * y + z * z), fabs(w));
}

static void quat_mul(const double a[4], const double b[4], double o[4])
{
    o[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    o[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    o[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    o[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

static void test_picard(void)
{
    vec3 w = v3(0.3, -0.2, 0.5);
    real T = 0.004, q[4], q0r[4];
    double q1[4], q0[4];
    euler_to_quat((euler){ 10 * DEG, -5 * DEG, 30 * DEG }, q0r);
    memcpy(q, q0r, sizeof q);
    for (int i = 0; i < 4; i++)
        q1[i] = q0[i] = q0r[i];
    int n = 2500;
    for (int k = 0; k < n; k++) {
        picard2(q, w, T);
        /* first order, for contrast: the same update without the -dtheta^2/8 term */
        double a = w.x * T / 2, b = w.y * T / 2, c = w.z * T / 2, p[4];
        p[0] = q1[0] - a * q1[1] - b * q1[2] - c * q1[3];
        p[1] = q1[1] + a * q1[0] + c * q1[2] - b * q1[3];
        p[2] = q1[2] + b * q1[0] - c * q1[1] + a * q1[3];
        p[3] = q1[3] + c * q1[0] + b * q1[1] - a * q1[2];
        double nn = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]);
        for (int i = 0; i < 4; i++)
            q1[i] = p[i] / nn;
    }
    /* exact: q(t) = q0 * exp(w t / 2), a constant body rate is a fixed-axis rotation */
    double th = v3_norm(w) * n * T, s = sin(th / 2) / v3_norm(w), dq[4] = { cos(th / 2), w.x * s, w.y * s, w.z * s };
    double exact[4];
    quat_mul(q0, dq, exact);
    real q1r[4] = { q1[0], q1[1], q1[2], q1[3] };
    double err2 = angle_between(q, exact), err1 = angle_between(q1r, exact);
    check(err2 < PREC(2e-6, 5e-5), "picard2 matches the exact rotation after 10 s at 0.62 rad/s", "error %g rad (%g)",
          err2, 0);
    /* normalising a first-order step recovers most of the second-order term, so the margin is modest */
    /* (in float the roundings of 2500 steps, 1.8e-5 rad, outweigh the second-order term: no contest) */
    if (!PREC(0, 1))
        check(err2 < err1, "picard2 beats the normalised first-order update", "%g vs %g", err2, err1);
}

static const vec3 M_EARTH = { 0.25, 0.0, 0.433 };

static void truth_at(euler e, vec3 *acc, vec3 *mag)
{
    mahony_dcm t;
    mahony_init(&t, 0, 0);
    mahony_set_euler(&t, e);
    real(*R)[3] = t.R;         /* body -> earth */
    vec3 g = v3(0, 0, -FC_G0); /* specific force at rest, earth axes: -g along down */
    *acc = v3(R[0][0] * g.x + R[1][0] * g.y + R[2][0] * g.z, R[0][1] * g.x + R[1][1] * g.y + R[2][1] * g.z,
              R[0][2] * g.x + R[1][2] * g.y + R[2][2] * g.z);
    vec3 m = M_EARTH;
    *mag = v3(R[0][0] * m.x + R[1][0] * m.y + R[2][0] * m.z, R[0][1] * m.x + R[1][1] * m.y + R[2][1] * m.z,
              R[0][2] * m.x + R[1][2] * m.y + R[2][2] * m.z);
}

static double euler_err(euler a, euler b)
{
    double dy = remainder(a.yaw - b.yaw, 2 * M_PI);
    return fmax(fabs(a.roll - b.roll), fmax(fabs(a.pitch - b.pitch), fabs(dy)));
}

static void test_convergence(void)
{
    euler truth = { 0, 0, 40 * DEG }, start = { 30 * DEG, -30 * DEG, 70 * DEG };
    vec3 acc, mag, bias = v3(0.5 * DEG, -0.4 * DEG, 0.3 * DEG);
    truth_at(truth, &acc, &mag);
    quat_cf cf;
    mahony_dcm mh;
    quat_cf_init(&cf, 0.3, 0.01);
    mahony_init(&mh, 0.3, 0.01);
    quat_cf_set_euler(&cf, start);
    mahony_set_euler(&mh, start);
    /* with Kp = 0.3, Ki = 0.01 the slow pole is tens of seconds (the yaw loop sees only the field's
       horizontal half), so give them 500 s */
    real T = 0.004;
    for (int k = 1; k <= 500 * 250; k++) {
        quat_cf_update(&cf, bias, acc, mag, T);
        mahony_update(&mh, bias, acc, mag, T);
    }
    double e_cf = euler_err(quat_to_euler(cf.q), truth), e_mh = euler_err(dcm_to_euler(mh.R), truth);
    check(e_cf < 0.01 * DEG, "seed-000 filter converges from 30 deg and holds a gyro bias out",
          "error after 500 s %g deg%g", e_cf / DEG, 0);
    check(e_mh < 0.01 * DEG, "Mahony DCM converges from 30 deg and holds a gyro bias out", "error after 500 s %g deg%g",
          e_mh / DEG, 0);
    vec3 lc = v3_scale(cf.integral, 0.01), lm = v3_scale(mh.integral, 0.01);
    check(v3_norm(v3_add(lc, bias)) < 1e-3 * DEG && v3_norm(v3_add(lm, bias)) < 1e-3 * DEG,
          "both integral terms learn the gyro bias exactly", "%g %g", v3_norm(v3_add(lc, bias)),
          v3_norm(v3_add(lm, bias)));
    double ortho = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = 0;
            for (int k = 0; k < 3; k++)
                d += mh.R[i][k] * mh.R[j][k];
            ortho = fmax(ortho, fabs(d - (i == j)));
        }
    check(ortho < PREC(1e-9, 1e-6), "the DCM stays orthonormal", "max |R R^T - I| %g%g", ortho, 0);
}

static double lcg_noise(unsigned *s)
{
    *s = *s * 1664525u + 1013904223u;
    return ((*s >> 8) / 16777216.0 - 0.5) * 2;
}

static void test_ekf_vs_mahony(void)
{
    mahony_dcm mh;
    ekf7 kf;
    mahony_init(&mh, 0.3, 0.01);
    ekf_init(&kf);
    double T = 0.004, worst = 0, worst_truth = 0;
    unsigned seed = 1;
    for (int k = 0; k < 60 * 250; k++) {
        double t = k * T;
        euler e = { 20 * DEG * sin(0.5 * t), 15 * DEG * sin(0.3 * t + 1), 30 * DEG * sin(0.2 * t) };
        double dr = 20 * DEG * 0.5 * cos(0.5 * t), dp = 15 * DEG * 0.3 * cos(0.3 * t + 1),
               dy = 30 * DEG * 0.2 * cos(0.2 * t);
        vec3 w = v3(dr - dy * sin(e.pitch), dp * cos(e.roll) + dy * cos(e.pitch) * sin(e.roll),
                    -dp * sin(e.roll) + dy * cos(e.pitch) * cos(e.roll));
        vec3 acc, mag;
        truth_at(e, &acc, &mag);
        w = v3_add(w, v3(0.002 * lcg_noise(&seed), 0.002 * lcg_noise(&seed), 0.002 * lcg_noise(&seed)));
        acc = v3_add(acc, v3(0.05 * lcg_noise(&seed), 0.05 * lcg_noise(&seed), 0.05 * lcg_noise(&seed)));
        if (k == 0) {
            mahony_set_euler(&mh, e);
            ekf_set_euler(&kf, e);
        }
        mahony_update(&mh, w, acc, mag, T);
        ekf_update(&kf, w, acc, mag, T);
        if (t > 5) {
            worst = fmax(worst, euler_err(dcm_to_euler(mh.R), ekf_euler(&kf)));
            worst_truth = fmax(worst_truth, fmax(euler_err(dcm_to_euler(mh.R), e), euler_err(ekf_euler(&kf), e)));
        }
    }
    check(worst < 1.0 * DEG, "EKF and Mahony agree on a recorded motion", "worst difference %g deg%g", worst / DEG, 0);
    check(worst_truth < 1.5 * DEG, "both track the true motion", "worst error %g deg%g", worst_truth / DEG, 0);
}

static void test_pid(void)
{
    pid p;
    pid_init(&p, 1.3, 0.7, 0.05, 0, 0);
    double T = 0.01, sum = 0, prev = 0, worst = 0;
    unsigned seed = 7;
    for (int t = 0; t < 500; t++) {
        real e = lcg_noise(&seed) * 3;
        sum += e;
        double expected = 1.3 * e + 0.7 * sum * T + (t ? 0.05 * (e - prev) / T : 0.0); /* eq. 8 */
        prev = e;
        worst = fmax(worst, fabs(pid_step(&p, e, T) - expected));
    }
    check(worst < PREC(1e-12, 1e-4), "PID is seed 000 eq. 8 step by step", "worst difference %g%g", worst, 0);
    pid_init(&p, 1000, 0, 0, 100, 0);
    check(pid_step(&p, 1, T) == 100 && pid_step(&p, -1, T) == -100, "angle output limited to +-100 (eq. 13)", "%g %g",
          0, 0);
    /* conditional integration (the altitude loop): errors outside the band leave the sum alone */
    pid_init(&p, 0, 1, 0, 0, 0);
    p.i_band = 0.3;
    for (int t = 0; t < 100; t++)
        pid_step(&p, 1.0, T); /* a metre off: nothing summed */
    double outside = p.sum;
    pid_step(&p, 0.2, T);
    check(outside == 0 && fabs(p.sum - 0.2 * T) < PREC(1e-15, 1e-9),
          "PID integrates only inside its band when it has one", "sum %g after errors outside, %g after one inside",
          outside, p.sum);
}

static void test_mixers(void)
{
    /* torques from geometry: thrust T_i at (x_i, y_i) pushes -z, torque = r x F = (-y T, x T, 0); a
       counter-clockwise rotor (seen from above) turns the body clockwise: +yaw in NED */
    const double plus[4][3] = { { 1, 0, 1 }, { 0, -1, -1 }, { -1, 0, 1 }, { 0, 1, -1 } };
    const double x[4][3] = { { 1, 1, 1 }, { 1, -1, -1 }, { -1, -1, 1 }, { -1, 1, -1 } }; /* plant frame = 1 */
    const double(*geo[2])[3] = { plus, x };
    const char *names[2] = { "'+' mixer (eq. 15) turns commands into torques of the same sign",
                             "X mixer turns commands into torques of the same sign" };
    for (int kind = 0; kind < 2; kind++) {
        int ok = 1;
        for (int axis = 0; axis < 3; axis++) {
            real out[4];
            double tau[3] = { 0 };
            mix((enum mixer_kind)kind, 500, axis == 0, axis == 1, axis == 2, out);
            for (int m = 0; m < 4; m++) {
                double d = out[m] - 500;
                tau[0] += -geo[kind][m][1] * d;
                tau[1] += geo[kind][m][0] * d;
                tau[2] += geo[kind][m][2] * d;
            }
            for (int k = 0; k < 3; k++)
                ok &= (k == axis) ? tau[k] > 0 : fabs(tau[k]) < 1e-12;
        }
        check(ok, names[kind], "%g%g", 0, 0);
    }
    check(fabs(throttle_compensate(1500, 1.1, 1000) - 550.0) < PREC(1e-12, 1e-4),
          "throttle compensation is alpha (x - beta) (eq. 16)", "%g%g", throttle_compensate(1500, 1.1, 1000), 0);
}

static void test_ms5611(void)
{
    uint16_t an520[8] = { 0x3132, 0x3334, 0x3536, 0x3738, 0x3940, 0x4142, 0x4344, 0x4500 };
    uint16_t prom[8] = { 0, 40127, 36924, 23317, 23282, 33464, 28312, 0x0103 };
    check(ms5611_crc4(an520) == 0xB, "CRC-4 of the AN520 example is 0xB", "got %g%g", ms5611_crc4(an520), 0);
    check(ms5611_crc4(prom) == 3, "CRC-4 of the datasheet PROM with 0x0103 is 3", "got %g%g", ms5611_crc4(prom), 0);
    int32_t p, t;
    ms5611_compensate(prom, 9085466, 8569150, &p, &t);
    check(p == 100009 && t == 2007, "MS5611 datasheet example: 100009 Pa, 20.07 degC", "got %g Pa, %g", p, t);
    double h = 123.456, pr = 101325.0 * pow(1 - h / 44330.0, 1 / 0.1903);
    check(fabs(baro_altitude(pr, 101325.0) - h) < PREC(1e-9, 0.01), "barometric altitude is eq. 6", "%g vs %g",
          baro_altitude(pr, 101325.0), h);
}

/* A fake MS5611 behind the conversion cycle's bus: it answers an ADC read before the conversion has
   had 9.04 ms with 0, as the datasheet says, and counts such reads; its clock is the test's, and a
   command can take `cmd_delay` seconds to go out (a Linux loop preempted there). */
struct fake_baro {
    double now, cmd_delay, cmd_at;
    int phase, zero_once, early_reads, reads;
};

static int fake_xfer(void *ctx, const uint8_t *w, int wn, uint8_t *r, int rn)
{
    struct fake_baro *f = ctx;
    if (wn == 1 && (w[0] == 0x48 || w[0] == 0x58) && rn == 0) {
        f->now += f->cmd_delay;
        f->cmd_at = f->now;
        f->phase = w[0] == 0x48;
        return 0;
    }
    if (wn == 1 && w[0] == 0x00 && rn == 3) {
        uint32_t v = f->phase ? 9085466 : 8569150; /* the datasheet example's D1 and D2 */
        f->reads++;
        if (f->now - f->cmd_at < 0.00904) {
            f->early_reads++;
            v = 0;
        }
        if (f->zero_once) {
            f->zero_once = 0;
            v = 0;
        }
        r[0] = (uint8_t)(v >> 16);
        r[1] = (uint8_t)(v >> 8);
        r[2] = (uint8_t)v;
        return 0;
    }
    return -5;
}

static double fake_clock(void *ctx) { return ((struct fake_baro *)ctx)->now; }

static void test_ms5611_cycle(void)
{
    uint16_t prom[8] = { 0, 40127, 36924, 23317, 23282, 33464, 28312, 0x0103 };
    struct fake_baro f = { .now = 1.0 };
    ms5611_bus bus = { fake_xfer, fake_clock, &f };
    ms5611_dev d = { 0 };
    memcpy(d.prom, prom, sizeof prom);
    /* a 250 Hz loop whose convert commands go out up to 5 ms after the loop read its clock */
    unsigned seed = 7;
    int readings = 0, wrong = 0;
    for (int k = 0; k < 1000; k++) {
        f.cmd_delay = (lcg_noise(&seed) + 1) * 0.0025;
        int32_t p, t;
        int r = ms5611_poll(&d, &bus, &p, &t);
        readings += r == 1;
        wrong += r == 1 && (p != 100009 || t != 2007);
        f.now += 0.004;
    }
    check(f.early_reads == 0 && readings > 100 && !wrong,
          "MS5611 cycle: a conversion is timed from its command, never read early, however late the command",
          "%g early ADC reads, %g readings", f.early_reads, readings);
    /* the chip says "not finished" (0): no reading comes of it, the same conversion starts again */
    f.zero_once = 1;
    int phase = d.phase, before = readings;
    unsigned not_ready = d.not_ready;
    int32_t p = 0, t = 0;
    for (int k = 0; k < 4 && d.not_ready == not_ready; k++) {
        int r = ms5611_poll(&d, &bus, &p, &t);
        readings += r == 1;
        f.now += 0.004;
    }
    check(d.not_ready == not_ready + 1 && d.phase == phase && readings == before,
          "MS5611 cycle: an ADC result of 0 is not a reading; the conversion is repeated", "not_ready %g, readings %g",
          d.not_ready - not_ready, readings - before);
}

static void test_sbus(void)
{
    uint8_t f[SBUS_FRAME] = { 0x0F, 0xFF, 0x07 };
    f[23] = 0x0C;
    sbus_frame d;
    int r = sbus_decode(f, &d);
    check(r == 0 && d.ch[0] == 0x7FF && d.ch[1] == 0 && d.failsafe && d.frame_lost,
          "SBUS: channel 1 is the first 11 bits, LSB first; flags 0x0C are failsafe and frame lost", "ch0 %g, ch1 %g",
          d.ch[0], d.ch[1]);
    sbus_frame in = { .failsafe = 0, .frame_lost = 1 };
    unsigned seed = 3;
    for (int i = 0; i < 16; i++)
        in.ch[i] = (uint16_t)((lcg_noise(&seed) + 1) * 1000);
    sbus_encode(&in, f);
    sbus_decode(f, &d);
    check(memcmp(d.ch, in.ch, sizeof d.ch) == 0 && d.frame_lost && !d.failsafe, "SBUS encode/decode round trip", "%g%g",
          0, 0);
    uint8_t stream[3 * SBUS_FRAME + 7] = { 0x55, 0x0F, 0x01, 0xAA };
    memcpy(stream + 4, f, SBUS_FRAME);                      /* garbage, then a frame */
    memcpy(stream + 4 + SBUS_FRAME, f, SBUS_FRAME - 3);     /* a frame cut short */
    memcpy(stream + 4 + 2 * SBUS_FRAME - 3, f, SBUS_FRAME); /* and a good one */
    sbus_parser ps;
    sbus_parser_init(&ps);
    sbus_frame got;
    int any = 0;
    for (size_t i = 0; i < sizeof stream; i++)
        any |= sbus_feed(&ps, stream + i, 1, &got);
    check(any && ps.frames == 2 && memcmp(got.ch, in.ch, sizeof got.ch) == 0,
          "SBUS parser resynchronises across garbage and a cut frame", "frames %g, errors %g", ps.frames, ps.errors);
}

/* The start-up alignment (flight_init) in Linux's 1000 steps and the AVR's 100, to a vehicle resting at
   30 deg of roll, -20 of pitch, heading 10 deg: the two end within 0.05 deg of each other (measured:
   0.036 for seed 000, 2e-6 for Mahony). Mahony ends on the truth; seed 000 ends 1.4 deg off it either
   way (4 s at kp 5 leave its yaw short: its slow pole, the horizontal half of the field), as it always
   has on Linux, and the loop's gains take the rest out in flight. */
static void test_alignment(void)
{
    euler truth = { 30 * DEG, -20 * DEG, 10 * DEG };
    vec3 acc, mag;
    truth_at(truth, &acc, &mag);
    static fc_config c;
    config_defaults(&c);
    for (int est = 0; est < 2; est++) {
        euler e[2];
        for (int k = 0; k < 2; k++) {
            c.estimator = est;
            flight f;
            flight_init(&f, &c, v3(0, 0, 0), acc, mag, 0, k ? 1000 : 100, NULL);
            e[k] = est == 0 ? quat_to_euler(f.cf.q) : dcm_to_euler(f.mh.R);
        }
        double err = fmax(euler_err(e[0], truth), euler_err(e[1], truth)), apart = euler_err(e[0], e[1]);
        check(apart < 0.05 * DEG && err < (est ? 0.001 : 2.0) * DEG,
              est ? "Mahony: the AVR's 100-step alignment ends where the 1000-step one does, on the truth"
                  : "seed-000 CF: the AVR's 100-step alignment ends where the 1000-step one does",
              "apart %g deg, off the truth %g deg", apart / DEG, err / DEG);
    }
}

/* flight_control is flight_outer then flight_inner (the Linux FC's cycle, bit for bit); the AVR runs
   flight_inner alone between outer cycles: it acts on a fresh rate at once, and not on a gyro declared
   stuck (the outer loop's descent output stays). */
static void test_inner_outer(void)
{
    static fc_config c;
    config_defaults(&c);
    c.estimator = 1;
    static flight a, b;
    sbus_frame arm = { { 992, 992, 172, 992, 1811, 172, 992, 992, 992, 992, 992, 992, 992, 992, 992, 992 }, 0, 0 };
    flight *fs[2] = { &a, &b };
    for (int k = 0; k < 2; k++) {
        flight_init(fs[k], &c, v3(0, 0, 0), v3(0, 0, -9.8), v3(0.25, 0, 0.433), 0, 100, NULL);
        flight_rc(fs[k], &arm, 1.0);
    }
    int same = 1;
    for (int i = 0; i < 50; i++) {
        vec3 gyro = v3(0.1 * sin(i * 0.3), 0.05 * cos(i * 0.2), 0.02);
        for (int k = 0; k < 2; k++)
            flight_sense(fs[k], v3(0, 0, 9.8), gyro, NULL);
        flight_control(&a, 1.0 + i * 0.004);
        if (flight_outer(&b, 1.0 + i * 0.004) & FLIGHT_CONTROLLED)
            flight_inner(&b, b.Tc);
        same &= memcmp(a.out, b.out, sizeof a.out) == 0;
    }
    check(same && a.armed, "flight_control is flight_outer then flight_inner, bit for bit", "armed %g, same %g",
          a.armed, same);
    real before = b.out[0];
    flight_measure(&b, v3(0, 0, 9.8), v3(0.5, 0, 0), NULL); /* a roll rate appears: no outer cycle */
    int wrote = flight_inner(&b, 0.5 * b.Tc);
    real after = b.out[0];
    b.gyro_fault = 1;
    int wrote_stuck = flight_inner(&b, 0.5 * b.Tc);
    check(wrote && after != before && !wrote_stuck && b.out[0] == after,
          "flight_inner acts on a fresh rate between outer cycles, not on a stuck gyro", "out %g -> %g", before, after);
}
int main(void)
{
    test_inner_outer();
    test_alignment();
    test_picard();
    test_convergence();
    test_ekf_vs_mahony();
    test_pid();
    test_mixers();
    test_ms5611();
    test_ms5611_cycle();
    test_sbus();
    return failures ? 1 : 0;
}
