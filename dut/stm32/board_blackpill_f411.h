/* The board: a WeAct Black Pill, STM32F411CEU6 (25 MHz crystal, 100 MHz) with a GY-86 on I2C1 (SCL PB8,
   SDA PB9), motors on TIM3 CH1-CH4 (PA6, PA7, PB0, PB1), SBUS on USART1 RX (PA10), telemetry on USART2
   TX (PA2). These match the STM32 tier's board file stm32f411-blackpill-gy86 (its comment says why these
   pins); the alternate functions are DS10314's table 9. */
#ifndef BOARD_BLACKPILL_F411_H
#define BOARD_BLACKPILL_F411_H

/* 100 MHz from the 25 MHz HSE (RM0383 6.3.2): PLLM 25 (a 1 MHz VCO input, the jitter note's 1-2 MHz),
   PLLN 200 (VCO 200 MHz), PLLP 2: 100 MHz, PLLQ 4; APB1 HCLK / 2 (its 50 MHz maximum), APB2 HCLK / 1;
   three flash wait states (RM0383 table 5, 90-100 MHz at 2.7-3.6 V); the regulator at scale 1
   (PWR_CR.VOS = 11, RM0383 5.4.1) */
#define BOARD_PLLCFGR (25u | (200u << 6) | RCC_PLLCFGR_PLLSRC_HSE | (4u << 24))
#define BOARD_CFGR_PPRE RCC_CFGR_PPRE1_DIV2
#define BOARD_FLASH_LATENCY 3u
#define BOARD_PWR_VOS (3u << 14)
#define BOARD_NAME "STM32F411" /* in the start-up line */
#define BOARD_HCLK_HZ 100000000UL
#define BOARD_APB1_HZ 50000000UL  /* HCLK / 2; its timers run at twice this */
#define BOARD_APB2_HZ 100000000UL /* HCLK; its timers run at this (RM0383 figure 12) */

/* motors 1..4: S1 PA6 TIM3_CH1, S2 PA7 TIM3_CH2, S3 PB0 TIM3_CH3, S4 PB1 TIM3_CH4 (AF2). TIM3 counts
   1 us ticks (100 MHz / 100) to ARR 2040: 2041 us (490 Hz), as on the F405 board */
#define BOARD_MOTORS                                                                                    \
    {                                                                                                   \
        { TIM3_BASE, 1, PORT_A, 6, 2 }, { TIM3_BASE, 2, PORT_A, 7, 2 }, { TIM3_BASE, 3, PORT_B, 0, 2 }, \
            { TIM3_BASE, 4, PORT_B, 1, 2 },                                                             \
    }
#define BOARD_MOTOR_APB1ENR (1u << 1) /* TIM3 */
#define PWM_PSC 99u
#define PWM_ARR 2040u
#define PWM_MIN_US 1000
#define PWM_MAX_US 2000

/* I2C1 at 400 kHz from the 50 MHz APB1 (RM0383 18.6.8: fast mode, duty 2, CCR = 50 MHz / (3 x 400 kHz),
   rounded up: 397 kHz), TRISE for 300 ns: 50 MHz x 300 ns + 1 */
#define I2C_FREQ_MHZ 50u
#define I2C_FAST_CCR 42u
#define I2C_FAST_TRISE 16u
#define I2C1_SCL_PIN 8u /* PB8, SDA PB9 (AF4) */

#define SBUS_BAUD 100000UL /* 8E2 on USART1 (PCLK2 100 MHz / (16 x 62.5)): exact */
/* ... received into a circular buffer by DMA2 stream 5 channel 4 (USART1_RX, RM0383 table 28) */
#define SBUS_DMA DMA2_BASE
#define SBUS_DMA_EN RCC_AHB1ENR_DMA2EN
#define SBUS_DMA_STREAM 5u
#define SBUS_DMA_CHANNEL 4u
#define TELEMETRY_BAUD 500000UL /* 50 MHz / (16 x 6.25): exact */
/* telemetry on USART2 TX, PA2 AF7, its clock PCLK1 */
#define TELEMETRY_USART USART2_BASE
#define TELEMETRY_USART_HZ BOARD_APB1_HZ
#define TELEMETRY_USART_ENR RCC_APB1ENR
#define TELEMETRY_USART_EN RCC_APB1ENR_USART2EN
#define TELEMETRY_TX_PORT PORT_A
#define TELEMETRY_TX_PIN 2u
#define TELEMETRY_TX_AF 7u
/* ... sent by DMA1 stream 6 channel 4 (USART2_TX, RM0383 table 27), its interrupt on NVIC line 17 */
#define TELEMETRY_DMA DMA1_BASE
#define TELEMETRY_DMA_EN RCC_AHB1ENR_DMA1EN
#define TELEMETRY_DMA_STREAM 6u
#define TELEMETRY_DMA_CHANNEL 4u
#define TELEMETRY_DMA_IRQ 17u
#define TELEMETRY_DMA_HANDLER dma1_stream6_handler

#define TICKS_PER_S BOARD_HCLK_HZ
#define SYSTICK_HZ 1000u

#endif
