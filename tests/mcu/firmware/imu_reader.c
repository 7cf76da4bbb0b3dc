/* A flight controller's skeleton, for the engine's speed with the chip core (bench/mcu_rates.py) and the
 * sample feed in demand mode: wakes the MPU-6050, reads its 14 data bytes every millisecond at 400 kHz
 * (Timer2 at 1 kHz), and drives two ESC outputs at 400 Hz from them (Timer1, fast PWM, TOP = ICR1:
 * OC1A/OC1B). */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>
#include <util/twi.h>

#if defined(__AVR_ATmega2560__)
#define ESC_DDR DDRB
#define ESC_BITS (_BV(5) | _BV(6))
#else
#define ESC_DDR DDRB
#define ESC_BITS (_BV(1) | _BV(2))
#endif

static volatile uint8_t tick;

ISR(TIMER2_COMPA_vect) { tick = 1; }

static uint8_t twi(uint8_t control)
{
    TWCR = control | _BV(TWINT) | _BV(TWEN);
    while (!(TWCR & _BV(TWINT))) {
    }
    return TW_STATUS;
}

static void write_reg(uint8_t reg, uint8_t value)
{
    twi(_BV(TWSTA));
    TWDR = 0x68 << 1;
    twi(0);
    TWDR = reg;
    twi(0);
    TWDR = value;
    twi(0);
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
    while (TWCR & _BV(TWSTO)) {
    }
}

static void read_regs(uint8_t reg, uint8_t *out, uint8_t n)
{
    twi(_BV(TWSTA));
    TWDR = 0x68 << 1;
    twi(0);
    TWDR = reg;
    twi(0);
    twi(_BV(TWSTA));
    TWDR = 0x68 << 1 | 1;
    twi(0);
    for (uint8_t i = 0; i < n; i++) {
        twi(i + 1 < n ? _BV(TWEA) : 0);
        out[i] = TWDR;
    }
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
    while (TWCR & _BV(TWSTO)) {
    }
}

int main(void)
{
    TWBR = 12;
    write_reg(0x6B, 0x00); /* awake */
    write_reg(0x1A, 0x03); /* DLPF 44 Hz: 1 kHz sampling */
    write_reg(0x1B, 0x18); /* 2000 deg/s */
    ESC_DDR |= ESC_BITS;
    ICR1 = 4999; /* 400 Hz at 2 MHz */
    OCR1A = OCR1B = 2000;
    TCCR1A = _BV(COM1A1) | _BV(COM1B1) | _BV(WGM11);
    TCCR1B = _BV(WGM13) | _BV(WGM12) | _BV(CS11);
    OCR2A = 249; /* 1 kHz at 250 kHz */
    TCCR2A = _BV(WGM21);
    TCCR2B = _BV(CS22);
    TIMSK2 = _BV(OCIE2A);
    sei();
    uint8_t data[14];
    for (;;) {
        while (!tick) {
        }
        tick = 0;
        read_regs(0x3B, data, sizeof data);
        int16_t az = (int16_t)(data[4] << 8 | data[5]);
        OCR1A = 2000 + (uint16_t)(az >> 6);
        OCR1B = 2000 + (uint16_t)(data[8] << 2);
    }
}
