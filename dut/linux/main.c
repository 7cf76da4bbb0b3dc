/* fc: the reference flight controller on Linux. Usage: fc [config-file]
   Start-up: sensors (fail: message, exit 2, no motor output), gyro bias from 500 samples at rest,
   motors at idle; then a loop at est_rate_hz on absolute deadlines: read sensors, estimate, read RC;
   at ctrl_rate_hz control, mix, write PWM; emit telemetry. The flight logic is the platforms' common
   one (src/flight.c); this file is the Linux board: i2c-dev, sysfs PWM, serial paths, the clock. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "binary_telemetry.h"
#include "config.h"
#include "drivers.h"
#include "flight.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void ts_add(struct timespec *t, long ns)
{
    t->tv_nsec += ns;
    while (t->tv_nsec >= 1000000000L) {
        t->tv_nsec -= 1000000000L;
        t->tv_sec++;
    }
}

/* MSP: answers the requests that came since the last cycle; MAVLink: every telemetry_every cycles, a burst */
static void binary_telemetry(const fc_config *c, int fd, tel_link *link, const tel_snapshot *snap, unsigned long cycles)
{
    uint8_t out[TEL_OUT_MAX];
    uint16_t n = 0;
    if (c->telemetry_proto == FC_TEL_MSP) {
        uint8_t in[64];
        ssize_t got;
        while ((got = read(fd, in, sizeof in)) > 0)
            n += tel_msp_serve(link, snap, in, (uint16_t)got, out + n, (uint16_t)(sizeof out - n));
    } else if (cycles % (unsigned long)c->telemetry_every == 0) {
        n = tel_mavlink_burst(link, snap, out, sizeof out);
    }
    if (n > 0 && write(fd, out, n) < 0 && errno != EAGAIN)
        perror("fc: telemetry");
}

int main(int argc, char **argv)
{
    fc_config c;
    char err[256];
    config_defaults(&c);
    if (argc > 2 || (argc == 2 && config_load(&c, argv[1], err, sizeof err) < 0)) {
        fprintf(stderr, "fc: %s\n", argc > 2 ? "usage: fc [config-file]" : err);
        return 2;
    }
    int bus = i2c_open(c.i2c_path);
    if (bus < 0) {
        fprintf(stderr, "fc: cannot open %s: %s\n", c.i2c_path, strerror(errno));
        return 2;
    }
    ms5611_dev baro;
    i2c_target baro_at = { bus, c.baro_addr };
    ms5611_bus baro_bus = ms5611_on_i2c(&baro_at);
    if (mpu_init(bus, c.mpu_addr, err, sizeof err) < 0 || hmc_init(bus, c.hmc_addr, err, sizeof err) < 0 ||
        ms5611_init(bus, c.baro_addr, &baro, err, sizeof err) < 0) {
        fprintf(stderr, "fc: %s; no motor output\n", err);
        return 2;
    }
    FILE *tel = NULL; /* text lines */
    int tel_fd = -1;  /* MSP (read and written) or MAVLink */
    if (c.telemetry_path[0] && c.telemetry_proto == FC_TEL_TEXT)
        tel = fopen(c.telemetry_path, "w");
    else if (c.telemetry_path[0])
        tel_fd = open(c.telemetry_path, O_RDWR | O_NONBLOCK | O_NOCTTY);
    if (c.telemetry_path[0] && !tel && tel_fd < 0) {
        fprintf(stderr, "fc: cannot open telemetry %s: %s\n", c.telemetry_path, strerror(errno));
        return 2;
    }
    tel_link link;
    tel_link_init(&link);
    int rc = -1;
    if (c.rc_path[0] && (rc = open(c.rc_path, O_RDONLY | O_NONBLOCK | O_NOCTTY)) < 0) {
        fprintf(stderr, "fc: cannot open RC input %s: %s\n", c.rc_path, strerror(errno));
        return 2;
    }
    const double t_start = now_s();
    struct timespec next;
    long step_ns = (long)(1e9 / c.est_rate_hz);

    /* gyro bias: 500 samples at rest (seed 000); the field for the initial heading is averaged over the
       same second (one sample in 7, about the HMC5883L's 75 Hz): a single noisy sample started the
       heading a degree or two off, and the heading loop is slow to take that out */
    vec3 bias = v3(0, 0, 0), acc, gyro, mag = v3(0, 0, 0), acc_mean = v3(0, 0, 0), mag_sum = v3(0, 0, 0);
    int mag_n = 0;
    /* on absolute deadlines 2 ms apart: the second lasts a second however long the bus takes (on a bench
       each read costs real time; a relative sleep after it made calibration last 1.3 s there) */
    struct timespec cal;
    clock_gettime(CLOCK_MONOTONIC, &cal);
    for (int i = 0; i < 500; i++) {
        if (mpu_read(bus, c.mpu_addr, &acc, &gyro) < 0) {
            fprintf(stderr, "fc: MPU-6050 read failed during calibration; no motor output\n");
            return 2;
        }
        bias = v3_add(bias, v3_scale(flight_to_body(gyro), 1.0 / 500));
        acc_mean =
            v3_add(acc_mean, v3_scale(flight_calibrate(flight_to_body(acc), c.acc_offset, c.acc_scale), 1.0 / 500));
        vec3 m;
        if (i % 7 == 0 && hmc_read(bus, c.hmc_addr, &m) == 0) {
            mag_sum = v3_add(mag_sum, flight_calibrate(flight_to_body(m), c.mag_offset, c.mag_scale));
            mag_n++;
        }
        ts_add(&cal, 2000000L);
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &cal, NULL);
    }
    if (pwm_setup(c.pwm_chip, 4, 2500000, err, sizeof err) < 0) {
        fprintf(stderr, "fc: %s\n", err);
        return 2;
    }
    if (mag_n > 0)
        mag = v3_scale(mag_sum, 1.0 / mag_n);
    flight fl;
    flight_init(&fl, &c, bias, acc_mean, mag, 1, 1000, NULL);
    sbus_parser sp;
    sbus_parser_init(&sp);
    int reported_garbage = 0;
    unsigned long cycles = 0, overruns = 0;
    double loop_max_us = 0;

    /* the loop's deadlines start now: taken before the 1 s calibration, they made the first 250 cycles
       run back to back (counted as overruns) to catch up */
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (;;) {
        double t0 = now_s();
        if (mpu_read(bus, c.mpu_addr, &acc, &gyro) < 0) {
            fprintf(stderr, "fc: MPU-6050 read failed at t=%.3f; motors to idle and stop\n", t0);
            break;
        }
        if (c.defect_crash_at > 0 && t0 - t_start >= c.defect_crash_at)
            abort(); /* negative control: a firmware that crashes mid-flight */
        vec3 m, *mag_read = NULL;
        if (cycles % 4 == 0 && hmc_read(bus, c.hmc_addr, &m) == 0) /* the HMC5883L updates at 75 Hz */
            mag_read = &m;
        flight_sense(&fl, acc, gyro, mag_read);
        int32_t p_pa, t_c;
        if (ms5611_poll(&baro, &baro_bus, &p_pa, &t_c) == 1)
            flight_baro(&fl, p_pa, t0);
        /* RC */
        if (rc >= 0) {
            uint8_t buf[256];
            ssize_t n;
            sbus_frame f;
            while ((n = read(rc, buf, sizeof buf)) > 0)
                if (sbus_feed(&sp, buf, (size_t)n, &f))
                    flight_rc(&fl, &f, t0);
            if (sp.errors > 0 && !reported_garbage && sp.frames == 0 && sp.errors > 2 * SBUS_FRAME) {
                fprintf(stderr, "fc: RC input %s: %lu bytes that are not SBUS frames; staying disarmed\n", c.rc_path,
                        sp.errors);
                reported_garbage = 1;
            }
        }
        int events = flight_control(&fl, t0);
        if (events & (FLIGHT_GYRO_STUCK | FLIGHT_GYRO_RECOVERED))
            fprintf(stderr, "fc: gyro %s at t=%.3f\n",
                    events & FLIGHT_GYRO_STUCK ? "stuck: holding level torque, descending" : "recovered", t0);
        if (events & FLIGHT_RC_LOST)
            fprintf(stderr, "fc: RC lost at t=%.3f: failsafe (level, descend, disarm)\n", t0);
        if (events & FLIGHT_CONTROLLED)
            for (int i = 0; i < 4; i++)
                pwm_write_us(c.pwm_chip, i, fl.out[i]);
        double loop_us = (now_s() - t0) * 1e6;
        loop_max_us = fmax(loop_max_us, loop_us);
        if (tel_fd >= 0) {
            tel_snapshot snap = { (uint32_t)((t0 - t_start) * 1000), (uint16_t)fmin(loop_us, 65535), 0, &fl };
            binary_telemetry(&c, tel_fd, &link, &snap, cycles);
        }
        if (tel && cycles % (unsigned long)c.telemetry_every == 0) {
            fprintf(
                tel,
                "T t=%.4f roll=%.3f pitch=%.3f yaw=%.3f alt=%.3f armed=%d rc=%d gyro_fault=%d loop_us=%.0f max_us=%.0f "
                "overruns=%lu\n",
                t0, fl.att.roll * 180 / M_PI, fl.att.pitch * 180 / M_PI, fl.att.yaw * 180 / M_PI, fl.altf.h, fl.armed,
                fl.rc_ok, fl.gyro_fault, loop_us, loop_max_us, overruns);
            fflush(tel);
        }
        cycles++;
        ts_add(&next, step_ns);
        struct timespec cur;
        clock_gettime(CLOCK_MONOTONIC, &cur);
        if (cur.tv_sec > next.tv_sec || (cur.tv_sec == next.tv_sec && cur.tv_nsec > next.tv_nsec))
            overruns++;
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
    }
    for (int i = 0; i < 4; i++)
        pwm_write_us(c.pwm_chip, i, 1000);
    return 3;
}
