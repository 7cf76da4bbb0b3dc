/* The reference flight controller as STM32F405 or STM32F411 firmware (docs/reference-fc.md; the board's
   pins, timers and clock in board.h). The same flight logic as the Linux FC (src/flight.c) in the Linux
   FC's loop: the GY-86 on I2C1, the board's four motor timer channels, SBUS on USART1, telemetry on the
   board's USART, the configuration from an image in flash (blank: the defaults).

   Start-up: motors at 1000 us at once (ESCs arm on it); the configuration; the chips (failure: a
   message, the motor outputs off, as the Linux FC exits without motor output); the gyro bias from 500
   samples 2 ms apart; then a loop at est_rate_hz on absolute millisecond deadlines of SysTick, the core
   asleep in WFI between, with overruns counted: read the burst, estimate, the barometer, the RC
   frames, control, the motors, a "T ..." line every telemetry_every cycles. With a single-precision
   FPU at 168 MHz (or the F411's 100 MHz) the whole cycle fits at the Linux FC's 250 Hz (the AVR splits it over two slots). */
#include "board.h"
#include "clock.h"
#include "config_image.h"
#include "flight.h"
#include "motors.h"
#include "sbus_rx.h"
#include "sensors.h"
#include "telemetry.h"
#include "twi.h"

/* the configuration image (config_image.h) in its own flash section; the ELF's copy is blank (0xFF:
   the defaults), as a chip's erased flash is */
__attribute__((section(".fc_config"),
               used)) static const uint8_t config_image[FC_IMAGE_SIZE] = { [0 ... FC_IMAGE_SIZE - 1] = 0xFF };

static fc_config cfg;
static flight fl;
static ms5611_dev baro;
static uint8_t baro_addr;

/* No motor output, for good: the outputs stop, the message repeats every second so a late listener
   sees it. */
static void halt(const char *why)
{
    motors_off();
    for (;;) {
        telemetry_say(why, "; no motor output");
        clock_sleep_until_ms(clock_ms() + 1000);
    }
}

int main(void)
{
    clock_init();
    motors_init(); /* 1000 us from the first period: the ESCs arm */
    telemetry_init();
    sbus_rx_init();
    twi_init();
    __asm volatile("cpsie i");
    telemetry_say(BOARD_NAME " reference FC", "");
    int st = config_from_image(&cfg, config_image, sizeof config_image);
    const char *cfg_why = st == FC_IMAGE_OK ? "flash" : fc_image_why(st); /* anything else: the defaults */
    telemetry_say(st == FC_IMAGE_OK ? "configuration: flash image" : "configuration: the defaults; flash image: ",
                  st == FC_IMAGE_OK ? "" : cfg_why);
    baro_addr = (uint8_t)cfg.baro_addr;
    ms5611_bus baro_bus = sensors_baro_bus(&baro_addr);
    int r = sensors_init((uint8_t)cfg.mpu_addr, (uint8_t)cfg.hmc_addr, baro_addr, &baro, NULL);
    if (r < 0)
        halt(sensors_why(r));

    /* gyro bias: 500 samples at rest, 2 ms apart on absolute deadlines; the field averaged over the
       same second (one sample in 7), as the Linux FC does */
    vec3 bias = v3(0, 0, 0), acc, gyro, mag, acc_mean = v3(0, 0, 0), mag_sum = v3(0, 0, 0);
    int mag_n = 0, mag_ok;
    telemetry_say("calibrating: one second at rest", "");
    uint32_t next = clock_ms();
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
        next += 2;
        clock_sleep_until_ms(next);
    }
    /* the alignment: the Linux FC's 1000 steps (4 s of the filters' time), the configured estimator's */
    flight_init(&fl, &cfg, bias, acc_mean, mag_n > 0 ? v3_scale(mag_sum, 1.0 / mag_n) : v3(0, 0, 0), 0, 1000, NULL);
    telemetry_say("running", "");

    const uint32_t period_ms = (uint32_t)(1000 / cfg.est_rate_hz + 0.5);
    const uint32_t mag_every = cfg.est_rate_hz >= 93.75 ? (uint32_t)(cfg.est_rate_hz / 62.5 + 0.5) : 1;
    const double t_start = clock_seconds();
    uint32_t cycles = 0, overruns = 0, max_us = 0;
    next = clock_ms();
    for (;;) {
        uint32_t c0 = clock_ticks();
        double t0 = clock_seconds();
        if (sensors_read((uint8_t)cfg.mpu_addr, &acc, &gyro, &mag, &mag_ok) < 0) {
            for (uint8_t i = 0; i < 4; i++)
                motors_write_us(i, 1000);
            halt("MPU-6050 read failed in flight; motors to idle and stop");
        }
        if (cfg.defect_crash_at > 0 && t0 - t_start >= cfg.defect_crash_at)
            for (;;) /* negative control: a firmware that hangs mid-flight */
                ;
        /* a field every mag_every cycles (62.5 Hz: 4 at 250 Hz as on Linux; the HMC5883L runs at 75 Hz) */
        flight_sense(&fl, acc, gyro, cycles % mag_every == 0 && mag_ok ? &mag : NULL);
        int32_t p_pa = 0, t_c = 0;
        if (ms5611_poll(&baro, &baro_bus, &p_pa, &t_c) == 1)
            flight_baro(&fl, p_pa, t0);
        sbus_frame f;
        int got;
        while ((got = sbus_rx_take(&f)) != 0)
            if (got > 0)
                flight_rc(&fl, &f, t0);
        int events = flight_control(&fl, t0);
        if (events & FLIGHT_CONTROLLED)
            for (uint8_t i = 0; i < 4; i++)
                motors_write_us(i, (uint16_t)(fl.out[i] + 0.5));
        if (events & FLIGHT_GYRO_STUCK)
            telemetry_say("gyro stuck: holding level torque, descending", "");
        if (events & FLIGHT_GYRO_RECOVERED)
            telemetry_say("gyro recovered", "");
        if (events & FLIGHT_RC_LOST)
            telemetry_say("RC lost: failsafe (level, descend, disarm)", "");
        uint32_t loop_us = (clock_ticks() - c0) / (TICKS_PER_S / 1000000UL);
        if (loop_us > max_us)
            max_us = loop_us;
        if (cycles % (uint32_t)cfg.telemetry_every == 0) {
            tel_counters k = { loop_us, max_us, overruns, cfg_why, twi_counters, sbus_rx_counters() };
            telemetry_line(t0, &fl, &k);
        }
        cycles++;
        next += period_ms;
        if ((int32_t)(clock_ms() - next) >= 0) {
            overruns++;
            if ((int32_t)(clock_ms() - next) > (int32_t)(4 * period_ms))
                next = clock_ms(); /* far behind (a bus recovery): start again rather than race */
        }
        clock_sleep_until_ms(next);
    }
}
