/* The STM32G431's clock tree and watchdog (RM0440 §5-7, §42):
     clock_init_170mhz  SYSCLK = HCLK = PCLK1 = PCLK2 = 170 MHz from HSI16 through the PLL (no crystal
                        needed: the NUCLEO-G431KB and the WeAct board both run without one), voltage
                        range 1 in boost mode, 4 flash wait states
     watchdog_start     the independent watchdog (LSI, about 32 kHz) with a 100 ms timeout; returns 1
                        when the last reset was the watchdog's
     watchdog_feed      from the main loop, which runs every few microseconds */
#ifndef STM32G4_CLOCK_H
#define STM32G4_CLOCK_H

#define CLOCK_HZ 170000000u

void clock_init_170mhz(void);
int watchdog_start(void);
void watchdog_feed(void);

#endif
