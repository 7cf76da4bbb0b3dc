/* A battery monitor while a motor runs: motor 1's ESC output (motor1_pwm.h) pulses 1000 us (zero throttle)
 * for the first 25 readings, then 2000 us (full throttle); ADC0 is read every 10 ms or so and sent as a
 * line, "# adc 640", on USART0 at 115200 8N1 (adc_line.h, as adc_batt.c). */
#include "adc_line.h"
#include "motor1_pwm.h"
#include <util/delay.h>

int main(void)
{
    uart0_init(_BV(TXEN0));
    motor1_start(1000);
    adc0_init();
    for (uint8_t n = 0;; n++) {
        if (n == 25)
            OCR_MOTOR = 2000;
        send_reading(adc0_read());
        _delay_ms(10);
    }
}
