/* The board: an Arduino Mega 2560 (ATmega2560, 16 MHz crystal) with a GY-86 on the TWI, four ESCs on
   timers 3 and 4, an SBUS receiver (through the usual inverter) on USART1, telemetry on USART0 (the USB
   serial). These match the MCU tier's board file mega2560-gy86; docs/avr-fc.md has the wiring. */
#ifndef BOARD_H
#define BOARD_H

#define BOARD_F_CPU 16000000UL

/* motors 1..4 (the plant's numbering, the mixer's order): D2 PE4 OC3B, D3 PE5 OC3C, D5 PE3 OC3A,
   D6 PH3 OC4A. Phase-correct PWM, TOP = ICRn = 2040, prescaler 8: 0.5 us ticks, a period of
   2 x 2040 ticks = 2.04 ms (490 Hz); the output is high for 2 x OCR ticks, so OCR = the pulse in us */
#define PWM_TOP 2040
#define PWM_MIN_US 1000
#define PWM_MAX_US 2000

#define TWI_HZ 400000UL
#define SBUS_BAUD 100000UL      /* 8E2; UBRR 9 at 16 MHz, exact */
#define TELEMETRY_BAUD 500000UL /* U2X, UBRR 3 at 16 MHz, exact */

/* The estimator's and the outer loops' rate at most, and the rate loop's multiple of it: float
   arithmetic is libm calls on this CPU. The rate loop (the MPU burst, the rate PIDs, the motors) runs
   AVR_INNER_PER_EST times a cycle, so that the time from a gyro sample to the pulses is the burst and the
   rate PIDs (about 1.4 ms) plus the PWM's latch, not an estimator's update besides; the estimator and the
   outer loops (with the barometer, the RC frames and the telemetry) take alternate slots. The slot with
   the estimator is the longest: 76,000 cycles in bench/avr_fc_cycles.py, up to 6.25 ms (100,000) measured
   in the MCU tier (max_us), so a slot is 6.67 ms: 150 Hz for the rate loop, 75 Hz for the rest (5 ms,
   200 and 100 Hz, overran every cycle). A configuration asking for more (the library's 250 Hz) runs at
   this rate, its control and telemetry rates scaled alike. */
#define AVR_RATE_HZ 75
#define AVR_RATE_TEXT "75"
#define AVR_INNER_PER_EST 2

/* A gyro repeating one sample this many times in a row (the rate loop's samples, 150 Hz: 20 ms) while
   armed is declared stuck (flight.h; Linux: 40 ms, 10 samples at 250 Hz). A stuck sample is what the
   rate loop acts on until then, at the Linux gain, and this board's rate loop rings a little where
   Linux's does not (its sample-to-pulse delay): in fault_gyro_stuck the stuck pitch rate is 10 deg/s,
   and 40 ms of it spun the vehicle up to 80 deg/s (a 16 deg flip, limit 15). Three equal readings of
   all three axes of a live MPU-6050 (several LSB of noise at 0.06 deg/s each) do not happen; three is
   flight.c's least. */
#define AVR_STUCK_SAMPLES 3

/* the initial alignment (flight.h) runs during the calibration second, a filter step every 3 samples
   (166 steps of 24 ms: the Linux FC's 4 s of the filters' time, which it runs in 1000 steps after the
   second). A step takes up to 2.6 ms here: one every 2 samples stretched the second by 12 %, and 1000
   after it started the loop at 2.7 s, after the library's scenarios arm (1.2 s); now it starts at
   1.13 s (Linux: 1.10) */
#define AVR_ALIGN_EVERY 3

/* The rate loop's gain when the configuration leaves it (no rate_kp, no profile): the Linux FC's 40.
   The former single 100 Hz loop needed 25 (4-5 ms from sample to pulse made 40 a 7 Hz limit cycle of
   1.6 deg rms in step_roll), and 25 left degraded_motor 5.1 deg off level (limit 4); the rate loop at
   150 Hz, 1.4 ms from the burst to the compare registers, flies 40 (docs/avr-fc.md, "Rate loop gain") */
#define AVR_RATE_KP 40

/* the clock: timer 1, prescaler 8, free-running: 2 ticks per microsecond */
#define TICKS_PER_S 2000000UL

#endif
