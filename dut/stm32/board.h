/* The board: an STM32F405 flight controller (8 MHz crystal, 168 MHz) with a GY-86 on I2C1 (SCL PB6,
   SDA PB7), the Omnibus F4's motor outputs, SBUS on USART1 RX (PA10), telemetry on USART6 TX (PC6).
   These match the STM32 tier's board file stm32f405-gy86; docs/reference-fc.md has the wiring. */
#ifndef BOARD_H
#define BOARD_H

#define BOARD_HCLK_HZ 168000000UL
#define BOARD_APB1_HZ 42000000UL /* HCLK / 4; its timers run at twice this */
#define BOARD_APB2_HZ 84000000UL /* HCLK / 2 */

/* motors 1..4 (the plant's numbering, the mixer's order): S1 PB0 TIM3_CH3, S2 PB1 TIM3_CH4, S3 PA3
   TIM2_CH4, S4 PA2 TIM2_CH3. The timers count 1 us ticks (84 MHz / 84) to ARR 2040: a period of
   2041 us (490 Hz, the AVR build's ESC rate), PWM mode 1 with CCR preloaded, so CCR = the pulse in us */
#define PWM_PSC 83u
#define PWM_ARR 2040u
#define PWM_MIN_US 1000
#define PWM_MAX_US 2000

/* I2C1 at 400 kHz from the 42 MHz APB1 (RM0090 27.6.8: fast mode, duty 2, CCR = 42 MHz / (3 x 400 kHz)),
   TRISE for 300 ns */
#define I2C_FREQ_MHZ 42u
#define I2C_FAST_CCR 35u
#define I2C_FAST_TRISE 13u

#define SBUS_BAUD 100000UL      /* 8E2; 84 MHz / (16 x 52.5): exact */
#define TELEMETRY_BAUD 500000UL /* 84 MHz / (16 x 10.5): exact */

/* the clock: DWT's cycle counter at HCLK */
#define TICKS_PER_S BOARD_HCLK_HZ

/* the loop's time base: SysTick every millisecond, the core asleep in WFI between (under QEMU's
   icount a sleeping core costs nothing; docs/mcu.md "Speed") */
#define SYSTICK_HZ 1000u

#endif
