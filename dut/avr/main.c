/* The reference flight controller as ATmega2560 firmware (docs/avr-fc.md). The same flight logic as the
   Linux FC (src/flight.c) on this board: the GY-86 on the TWI, motors on timers 3 and 4, SBUS on USART1,
   telemetry on USART0, the configuration in EEPROM (defaults in flash), a watchdog.

   Start-up: motors at 1000 us at once (ESCs arm on it); the configuration from EEPROM (a bad image: the
   defaults, and the telemetry says why); the chips (failure: a message, the motor outputs off, as the
   Linux FC exits without motor output); the gyro bias from 500 samples 2 ms apart; then a loop at
   est_rate_hz on absolute deadlines of the clock, with overruns counted. A "T ..." line every
   telemetry_every cycles, in the Linux FC's keys (and the AVR's counters); "# fc: ..." lines say what
   happened (start-up, faults). The EKF (estimator = 2) is not built here: 2 is refused at start-up. */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>
#include <string.h>

#include "binary_telemetry.h"
#include "board.h"
#include "clock.h"
#include "config_image.h"
#include "flight.h"
#include "motors.h"
#include "sbus_rx.h"
#include "sensors.h"
#include "telemetry.h"
#include "twi.h"
#include "uart0.h"

/* the EEPROM holds the configuration image at address 0; the ELF's copy is blank (0xFF: the defaults),
   and the rig or avrdude writes a scenario's (scenarios/eeprom.py) */
static const uint8_t ee_image[FC_IMAGE_SIZE] EEMEM = { [0 ... FC_IMAGE_SIZE - 1] = 0xFF };

static uint8_t reset_cause __attribute__((section(".noinit")));

/* before main: after a watchdog reset the watchdog stays on at its shortest period; turn it off first */
void early(void) __attribute__((naked, used, section(".init3")));
void early(void)
{
    reset_cause = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

static fc_config cfg;
static flight fl;
static ms5611_dev baro;
static uint8_t baro_addr;
static const char *cfg_why = "";

static void feed(void) { wdt_reset(); }

static void say(const char *a, const char *b)
{
    char buf[120];
    line l = { buf, 0, sizeof buf - 1 };
    line_str(&l, "# fc: ");
    line_str(&l, a);
    line_str(&l, b);
    buf[l.n++] = '\n';
    while (uart0_line(buf, l.n) < 0) /* start-up and fault messages wait for room: they must arrive */
        wdt_reset();
}

/* No motor output, for good: the outputs stop (ESCs without a signal do not run), the message repeats
   every second so a late listener sees it. */
static void halt(const char *why)
{
    motors_off();
    for (;;) {
        say(why, "; no motor output");
        uint32_t t = clock_ticks();
        while (clock_ticks() - t < TICKS_PER_S)
            wdt_reset();
    }
}

static uint16_t wraps; /* the 32-bit clock's wraps (every 2147 s), for the telemetry's t */
static uint32_t last_ticks;

static tel_link link; /* MSP's request parser, MAVLink's sequence */

static tel_snapshot snapshot(double t0, uint32_t loop_ticks)
{
    uint16_t errors = twi_counters.nacks + twi_counters.timeouts + twi_counters.bus_errors;
    tel_snapshot s = { (uint32_t)(t0 * 1000), (uint16_t)(loop_ticks / 2), errors, &fl };
    return s;
}

/* MSP (each outer slot): the requests received, answered at once */
static void msp_serve(double t0, uint32_t loop_ticks)
{
    uint8_t in[32], out[TEL_OUT_MAX];
    uint8_t n = uart0_take(in, sizeof in);
    if (n == 0)
        return;
    tel_snapshot s = snapshot(t0, loop_ticks);
    uint16_t m = tel_msp_serve(&link, &s, in, n, out, sizeof out);
    if (m > 0)
        uart0_line((const char *)out, (uint8_t)m);
}

static void telemetry(uint32_t loop_ticks, uint32_t max_ticks, uint32_t overruns, double t0)
{
    char buf[TELEMETRY_LINE];
    if (cfg.telemetry_proto == FC_TEL_MAVLINK) {
        tel_snapshot s = snapshot(t0, loop_ticks);
        uart0_line(buf, (uint8_t)tel_mavlink_burst(&link, &s, (uint8_t *)buf, TEL_OUT_MAX));
        return;
    }
    tel_counters k = { loop_ticks, max_ticks, overruns, cfg_why, twi_counters, sbus_rx_counters(), uart0_dropped() };
    uint32_t now = clock_ticks();
    if (now < last_ticks)
        wraps++;
    last_ticks = now;
    uart0_line(buf, telemetry_line(buf, wraps, now, &fl, &k));
}

int main(void)
{
    motors_init(); /* 1000 us from the first moment: the ESCs arm */
    clock_init();
    uart0_init();
    sbus_rx_init();
    twi_init();
    sei();
    wdt_enable(WDTO_250MS);
    {
        static const char hex[] = "0123456789abcdef";
        char cause[3] = { hex[reset_cause >> 4], hex[reset_cause & 15], 0 };
        /* MCUSR: 1 power-on, 2 external, 4 brown-out, 8 watchdog */
        say("ATmega2560 reference FC; reset cause (MCUSR) 0x", cause);
    }
    {
        uint8_t img[FC_IMAGE_SIZE];
        eeprom_read_block(img, ee_image, sizeof img);
        int st = config_from_image(&cfg, img, sizeof img);
        cfg_why = st == FC_IMAGE_OK ? "eeprom" : fc_image_why(st); /* anything else: the defaults */
        int own_gain = st != FC_IMAGE_OK || (!fc_image_sets(img, FC_KEY_INDEX_rate_kp) && !fc_image_has_profile(img));
        if (own_gain) /* this board's default (board.h): the configuration did not choose */
            cfg.rate_kp = AVR_RATE_KP;
        say(st == FC_IMAGE_OK ? "configuration: EEPROM image" : "configuration: the defaults; EEPROM image: ",
            st == FC_IMAGE_OK ? "" : cfg_why);
    }
    if (cfg.est_rate_hz > AVR_RATE_HZ) { /* as fast as this CPU goes; the rates keep their ratios */
        real k = AVR_RATE_HZ / cfg.est_rate_hz;
        cfg.est_rate_hz = AVR_RATE_HZ;
        cfg.ctrl_rate_hz *= k;
        cfg.telemetry_every = (int)(cfg.telemetry_every * k + 0.5);
        if (cfg.telemetry_every < 1)
            cfg.telemetry_every = 1;
        say("est_rate_hz is over what the AVR fits: the loop runs at ", AVR_RATE_TEXT " Hz");
    }
    tel_link_init(&link);
    if (cfg.telemetry_proto == FC_TEL_MSP)
        uart0_listen();
    if (cfg.estimator == 2)
        halt("estimator 2 (the EKF) is not built for the AVR: it does not fit the cycle budget");
    baro_addr = (uint8_t)cfg.baro_addr;
    ms5611_bus baro_bus = sensors_baro_bus(&baro_addr);
    int r = sensors_init((uint8_t)cfg.mpu_addr, (uint8_t)cfg.hmc_addr, baro_addr, &baro, feed);
    if (r < 0)
        halt(sensors_why(r));

    /* gyro bias: 500 samples at rest, 2 ms apart on absolute deadlines; the field averaged over the
       same second (one sample in 7), as the Linux FC does. The alignment (flight.h) runs meanwhile, a
       step every AVR_ALIGN_EVERY samples on the means so far, in the time the samples leave */
    vec3 bias = v3(0, 0, 0), acc, gyro, mag, acc_mean = v3(0, 0, 0), mag_sum = v3(0, 0, 0);
    int mag_n = 0, mag_ok;
    say("calibrating: one second at rest", "");
    flight_start(&fl, &cfg, 0);
    const real Ta = 4.0 / (500 / AVR_ALIGN_EVERY); /* 4 s of the filters' time in all, as on Linux */
    uint32_t next = clock_ticks();
    for (int i = 0; i < 500; i++) {
        if (sensors_read((uint8_t)cfg.mpu_addr, &acc, &gyro, &mag, &mag_ok) < 0)
            halt("MPU-6050 read failed during calibration");
        bias = v3_add(bias, v3_scale(flight_to_body(gyro), 1.0 / 500));
        acc_mean =
            v3_add(acc_mean, v3_scale(flight_calibrate(flight_to_body(acc), cfg.acc_offset, cfg.acc_scale), 1.0 / 500));
        if (i % 7 == 0 && mag_ok) {
            mag_sum = v3_add(mag_sum, flight_calibrate(flight_to_body(mag), cfg.mag_offset, cfg.mag_scale));
            mag_n++;
        }
        if (i % AVR_ALIGN_EVERY == AVR_ALIGN_EVERY - 1)
            flight_align(&fl, v3_scale(acc_mean, 500.0 / (i + 1)),
                         mag_n > 0 ? v3_scale(mag_sum, 1.0 / mag_n) : v3(0, 0, 0), Ta);
        next += TICKS_PER_S / 500;
        while ((int32_t)(clock_ticks() - next) < 0)
            ;
        wdt_reset();
    }
    flight_ready(&fl, bias, mag_n > 0 ? v3_scale(mag_sum, 1.0 / mag_n) : v3(0, 0, 0));
    /* the gyro check counts flight_measure's calls, the rate loop's samples: AVR_STUCK_SAMPLES (board.h) */
    fl.stuck_n = AVR_STUCK_SAMPLES;
    say("running", "");
    wdt_enable(WDTO_60MS); /* the loop feeds it every slot (6.67 ms) */

    /* Two slots per cycle of est_rate_hz (board.h): each reads the MPU burst and runs the rate loop on
       it at once (flight_measure, flight_inner, the motors); the first slot then runs the estimator,
       the second the outer loops on its estimate (flight_outer: the rate set points for the next slots),
       the barometer, the RC frames and the telemetry. The estimator (54 k cycles) and the outer work do
       not fit one 6.67 ms slot together; each fits beside the rate loop (bench/avr_fc_cycles.py). */
    const uint32_t period = (uint32_t)(TICKS_PER_S / (cfg.est_rate_hz * AVR_INNER_PER_EST) + 0.5);
    const real Ti = 1.0 / (cfg.est_rate_hz * AVR_INNER_PER_EST);
    const double t_start = clock_seconds();
    uint32_t cycles = 0, overruns = 0, max_ticks = 0;
    uint8_t slot = 0;
    int tel_due = 0;
    const uint8_t mag_every = cfg.est_rate_hz >= 93.75 ? (uint8_t)(cfg.est_rate_hz / 62.5 + 0.5) : 1;
    int mag_clean = 1;
    next = clock_ticks();
    for (;;) {
        uint32_t c0 = clock_ticks();
        double t0 = clock_seconds();
        if (sensors_read((uint8_t)cfg.mpu_addr, &acc, &gyro, &mag, &mag_ok) < 0) {
            for (uint8_t i = 0; i < 4; i++)
                motors_write_us(i, 1000);
            halt("MPU-6050 read failed in flight; motors to idle and stop");
        }
        if (cfg.defect_crash_at > 0 && t0 - t_start >= cfg.defect_crash_at)
            for (;;) /* negative control: a firmware that hangs mid-flight, until the watchdog resets it */
                ;
        mag_clean &= mag_ok;
        /* a field every mag_every cycles (62.5 Hz: 4 at 250 Hz as on Linux; the HMC5883L runs at 75 Hz),
           given to the estimator's slot */
        int mag_due = slot == 0 && cycles % mag_every == 0, fresh_mag = mag_due && mag_clean;
        if (mag_due)
            mag_clean = 1;
        /* the rate loop on this sample at once; out[] also holds what the outer loop set (disarmed,
           the gyro fault's descent) */
        flight_measure(&fl, acc, gyro, fresh_mag ? &mag : NULL);
        flight_inner(&fl, Ti);
        for (uint8_t i = 0; i < 4; i++)
            motors_write_us(i, (uint16_t)(fl.out[i] + 0.5));
        int baro_now = 0;
        if (slot == 0) {
            flight_estimate(&fl);
        } else {
            int events = flight_outer(&fl, t0);
            if (!fl.inner_on) /* disarmed, or the gyro fault's descent: out[] at once, not a slot later */
                for (uint8_t i = 0; i < 4; i++)
                    motors_write_us(i, (uint16_t)(fl.out[i] + 0.5));
            int32_t p_pa = 0, t_c = 0;
            if (ms5611_poll(&baro, &baro_bus, &p_pa, &t_c) == 1) {
                flight_baro(&fl, p_pa, t0);
                baro_now = 1;
            }
            sbus_frame f;
            int got;
            while ((got = sbus_rx_take(&f)) != 0)
                if (got > 0)
                    flight_rc(&fl, &f, t0);
            if (events & FLIGHT_GYRO_STUCK)
                say("gyro stuck: holding level torque, descending", "");
            if (events & FLIGHT_GYRO_RECOVERED)
                say("gyro recovered", "");
            if (events & FLIGHT_RC_LOST)
                say("RC lost: failsafe (level, descend, disarm)", "");
        }
        uint32_t loop_ticks = clock_ticks() - c0;
        if (loop_ticks > max_ticks)
            max_ticks = loop_ticks;
        if (slot == 1) {
            if (cycles % (uint32_t)cfg.telemetry_every == 0)
                tel_due = 1;
            /* a line and a barometer pair together overrun the slot: the line waits for the next
               outer slot (the pairs come every other one) */
            if (cfg.telemetry_proto == FC_TEL_MSP)
                msp_serve(t0 - t_start, loop_ticks);
            else if (tel_due && !baro_now) {
                telemetry(loop_ticks, max_ticks, overruns, t0 - t_start);
                tel_due = 0;
            }
            cycles++;
        }
        slot ^= 1;
        wdt_reset();
        next += period;
        if ((int32_t)(clock_ticks() - next) > 0) {
            overruns++;
            if ((int32_t)(clock_ticks() - next) > (int32_t)(4 * period))
                next = clock_ticks(); /* far behind (a bus recovery): start again rather than race */
        }
        while ((int32_t)(clock_ticks() - next) < 0)
            ;
    }
}
