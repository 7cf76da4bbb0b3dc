/* An ESC output that stops: motor 1's pin (motor1_pwm.h) pulses 1500 us at about 490 Hz for half a second,
 * then its compare output is disconnected and the firmware spins, as a firmware that crashed into a loop
 * would. */
#include "motor1_pwm.h"
#include <util/delay.h>

int main(void)
{
    motor1_start(1500);
    _delay_ms(500);
    motor1_stop();
    for (;;) {
    }
}
