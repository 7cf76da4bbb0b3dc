/* The AVR firmware's cycle budget: cycles per call of each part of its loop, counted by timer 1 at the
   CPU clock (prescaler 1) in simavr or on a Mega, on canned samples of a moving vehicle; printed on
   USART0 as "B <part> <cycles>" lines, then one telemetry line formatted from a known state (the rig's
   parser reads it back: tests/dut/test_avr_firmware.py), then "B end". bench/avr_fc_cycles.py runs it
   and prints the budget at 250 Hz. Built by `make -C dut avr-bench` (with the EKF, to measure it). */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <math.h>

#include "canned_motion.h"
#include "clock.h"
#include "config.h"
#include "flight.h"
#include "telemetry.h"
#include "uart0.h"

#define N 16

static vec3 gyro[N], acc[N], mag[N];

static void report(const char *name, uint32_t cycles, uint8_t n)
{
    char buf[64];
    line l = { buf, 0, sizeof buf - 1 };
    line_str(&l, "B ");
    line_str(&l, name);
    line_str(&l, " ");
    line_int(&l, (int32_t)(cycles / n));
    buf[l.n++] = '\n';
    uart0_line(buf, l.n);
    uart0_flush();
}

/* keeps the compiler from dropping a result */
static volatile real sink;

int main(void)
{
    clock_init();
    TCCR1B = _BV(CS10); /* the clock counts CPU cycles here */
    uart0_init();
    sei();
    for (uint8_t k = 0; k < N; k++)
        canned_motion(k, &gyro[k], &acc[k], &mag[k]);
    quat_cf cf;
    mahony_dcm mh;
    ekf7 kf;
    quat_cf_init(&cf, 0.3, 0.01);
    mahony_init(&mh, 0.3, 0.01);
    ekf_init(&kf);
    uint32_t t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++) {
        quat_cf_update(&cf, gyro[k], acc[k], mag[k], 0.004);
        sink = quat_to_euler(cf.q).roll;
    }
    report("estimator_cf", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++) {
        mahony_update(&mh, gyro[k], acc[k], mag[k], 0.004);
        sink = dcm_to_euler(mh.R).roll;
    }
    report("estimator_mahony", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < 2; k++) {
        ekf_update(&kf, gyro[k], acc[k], mag[k], 0.004);
        sink = ekf_euler(&kf).roll;
    }
    report("estimator_ekf", clock_ticks() - t0, 2);

    /* the flight logic as the loop runs it: armed, in altitude hold (every PID runs), Mahony */
    static fc_config c;
    static flight fl;
    config_defaults(&c);
    c.estimator = 1;
    flight_init(&fl, &c, v3(0, 0, 0), v3(0, 0, -9.8), v3(0.25, 0, 0.433), 0, 100, NULL);
    sbus_frame f = { { 992, 992, 172, 992, 1811, 1811, 992, 992, 992, 992, 992, 992, 992, 992, 992, 992 }, 0, 0 };
    flight_rc(&fl, &f, 1.0);
    flight_control(&fl, 1.0); /* arms */
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        flight_sense(&fl, acc[k], gyro[k], k % 4 ? NULL : &mag[k]);
    report("flight_sense_mahony", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        flight_baro(&fl, 101325 - k, 1.0 + k * 0.02);
    report("flight_baro", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        sink = flight_control(&fl, 1.0 + k * 0.004);
    report("flight_control", clock_ticks() - t0, N);
    /* its halves, as the AVR loop runs them (the rate loop at twice the estimator's rate) */
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        flight_measure(&fl, acc[k], gyro[k], k % 4 ? NULL : &mag[k]);
    report("flight_measure", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        flight_estimate(&fl);
    report("flight_estimate_mahony", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        sink = flight_outer(&fl, 1.0 + k * 0.004);
    report("flight_outer", clock_ticks() - t0, N);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        sink = flight_inner(&fl, 0.005);
    report("flight_inner", clock_ticks() - t0, N);
    sink = fl.armed && fl.alt_hold; /* (the path measured: armed, holding altitude) */

    uint16_t prom[8] = { 0, 40127, 36924, 23317, 23282, 33464, 28312, 0x0103 };
    int32_t p, tc;
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++) {
        ms5611_compensate(prom, 9085466 + k, 8569150 + k, &p, &tc);
        sink = p + tc;
    }
    report("ms5611_compensate", clock_ticks() - t0, N);
    uint8_t frame[SBUS_FRAME];
    sbus_encode(&f, frame);
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++) {
        frame[1] = k; /* a new frame each time */
        sbus_decode(frame, &f);
        sink = f.ch[0];
    }
    report("sbus_decode", clock_ticks() - t0, N);

    /* the telemetry line, from a known state */
    fl.att = (euler){ 0.1, -0.2, 3.0 };
    fl.altf.h = -1.25;
    fl.armed = 1;
    fl.rc_ok = 1;
    fl.gyro_fault = 0;
    tel_counters tk = { 2468, 4000, 3, "eeprom", { 1, 2, 3, 4 }, { 5, 6, 7, 8 }, 9 };
    char buf[TELEMETRY_LINE];
    uint8_t n = 0;
    t0 = clock_ticks();
    for (uint8_t k = 0; k < N; k++)
        n = telemetry_line(buf, 1, 1000000000UL, &fl, &tk); /* 2^32 + 1e9 ticks: 2647.483648 s */
    report("telemetry_line", clock_ticks() - t0, N);
    uart0_line(buf, n);
    uart0_line("B end\n", 6);
    uart0_flush();
    cli();
    sleep_enable();
    sleep_cpu(); /* simavr ends here: asleep with interrupts off */
    for (;;)
        ;
}
