/* The firmware's clock on the STM32F405: ST's 168 MHz set-up from the 8 MHz crystal, DWT's cycle counter
   for time (extended past its 25 s wrap), and SysTick's millisecond tick the loop sleeps until. The same
   interface as the AVR build's clock.h (src/sensors.c uses it). */
#ifndef CLOCK_H
#define CLOCK_H

#include <stdint.h>

void clock_init(void);                  /* 168 MHz, DWT counting, SysTick at SYSTICK_HZ */
uint32_t clock_ticks(void);             /* HCLK cycles (wraps after 25.6 s; differences stay right) */
double clock_seconds(void);             /* seconds since clock_init */
void clock_wait_us(uint16_t us);        /* busy wait (start-up only: the chips' reset times) */
uint32_t clock_ms(void);                /* SysTick's milliseconds since clock_init */
void clock_sleep_until_ms(uint32_t ms); /* WFI until clock_ms() reaches ms */

#endif
