/* The board: an STM32F405 flight controller (8 MHz crystal, 168 MHz) with a GY-86 on I2C1 (SCL PB6,
   SDA PB7), the Omnibus F4's motor outputs, SBUS on USART1 RX (PA10), telemetry on USART6 TX (PC6).
   These match the STM32 tier's board file stm32f405-gy86; docs/reference-fc.md has the wiring. */
#ifndef BOARD_F405_GY86_H
#define BOARD_F405_GY86_H

/* ST's SystemClock_Config for an 8 MHz HSE (clock.c): PLL M 8, N 336, P 2 (168 MHz), Q 7; APB1 HCLK / 4,
   APB2 HCLK / 2; five flash wait states (RM0090 table 10, 2.7-3.6 V); the regulator at scale 1 */
#define BOARD_PLLCFGR (8u | (336u << 6) | RCC_PLLCFGR_PLLSRC_HSE | (7u << 24))
#define BOARD_CFGR_PPRE (RCC_CFGR_PPRE2_DIV2 | RCC_CFGR_PPRE1_DIV4)
#define BOARD_FLASH_LATENCY 5u
#define BOARD_PWR_VOS PWR_CR_VOS
#define BOARD_NAME "STM32F405" /* in the start-up line */
#define BOARD_HCLK_HZ 168000000UL
#define BOARD_APB1_HZ 42000000UL /* HCLK / 4; its timers run at twice this */
#define BOARD_APB2_HZ 84000000UL /* HCLK / 2 */

/* motors 1..4 (the plant's numbering, the mixer's order): S1 PB0 TIM3_CH3, S2 PB1 TIM3_CH4, S3 PA3
   TIM2_CH4, S4 PA2 TIM2_CH3 (timer, channel, port, pin, alternate function: DS8626 table 9), with their
   timers' clock enables in RCC_APB1ENR. The timers count 1 us ticks (84 MHz / 84) to ARR 2040: a period
   of 2041 us (490 Hz, the AVR build's ESC rate), PWM mode 1 with CCR preloaded, so CCR = the pulse in us */
#define BOARD_MOTORS                                                                                    \
    {                                                                                                   \
        { TIM3_BASE, 3, PORT_B, 0, 2 }, { TIM3_BASE, 4, PORT_B, 1, 2 }, { TIM2_BASE, 4, PORT_A, 3, 1 }, \
            { TIM2_BASE, 3, PORT_A, 2, 1 },                                                             \
    }
#define BOARD_MOTOR_APB1ENR ((1u << 0) | (1u << 1)) /* TIM2, TIM3 */
#define PWM_PSC 83u
#define PWM_ARR 2040u
#define PWM_MIN_US 1000
#define PWM_MAX_US 2000

/* I2C1 at 400 kHz from the 42 MHz APB1 (RM0090 27.6.8: fast mode, duty 2, CCR = 42 MHz / (3 x 400 kHz)),
   TRISE for 300 ns */
#define I2C_FREQ_MHZ 42u
#define I2C_FAST_CCR 35u
#define I2C_FAST_TRISE 13u
#define I2C1_SCL_PIN 6u /* PB6, SDA PB7 (AF4) */

#define SBUS_BAUD 100000UL /* 8E2; 84 MHz / (16 x 52.5): exact */
/* ... received into a circular buffer by DMA2 stream 5 channel 4 (USART1_RX, RM0090 table 43) */
#define SBUS_DMA DMA2_BASE
#define SBUS_DMA_EN RCC_AHB1ENR_DMA2EN
#define SBUS_DMA_STREAM 5u
#define SBUS_DMA_CHANNEL 4u
#define TELEMETRY_BAUD 500000UL /* 84 MHz / (16 x 10.5): exact */
/* telemetry on USART6 TX, PC6 AF8 (the Omnibus F4's UART6), its clock PCLK2 */
#define TELEMETRY_USART USART6_BASE
#define TELEMETRY_USART_HZ BOARD_APB2_HZ
#define TELEMETRY_USART_ENR RCC_APB2ENR
#define TELEMETRY_USART_EN RCC_APB2ENR_USART6EN
#define TELEMETRY_TX_PORT PORT_C
#define TELEMETRY_TX_PIN 6u
#define TELEMETRY_TX_AF 8u
/* ... sent by DMA2 stream 6 channel 5 (USART6_TX, RM0090 table 43), its interrupt on NVIC line 69 */
#define TELEMETRY_DMA DMA2_BASE
#define TELEMETRY_DMA_EN RCC_AHB1ENR_DMA2EN
#define TELEMETRY_DMA_STREAM 6u
#define TELEMETRY_DMA_CHANNEL 5u
#define TELEMETRY_DMA_IRQ 69u
#define TELEMETRY_DMA_HANDLER dma2_stream6_handler

/* the clock: DWT's cycle counter at HCLK */
#define TICKS_PER_S BOARD_HCLK_HZ

/* the loop's time base: SysTick every millisecond, the core asleep in WFI between (under QEMU's
   icount a sleeping core costs nothing; docs/mcu.md "Speed") */
#define SYSTICK_HZ 1000u

#endif
