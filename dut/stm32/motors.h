/* Four ESC outputs on TIM3 and TIM2 (board.h): 1000 us from motors_init on, so the ESCs arm at power-up
   and see idle until the flight logic says otherwise. */
#ifndef MOTORS_H
#define MOTORS_H

#include <stdint.h>

void motors_init(void);
void motors_write_us(uint8_t motor, uint16_t us); /* motor 0..3; clamped to 1000..2000 */
void motors_off(void); /* no pulses at all: the channels' outputs off (an ESC without a signal does not run) */

#endif
