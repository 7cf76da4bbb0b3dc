/* A firmware that is talked to over MSP v1, as MultiWii is: USART0 at 115200 8N1 (U2X).
 *   At boot it finds the MPU-6050 at 0x68 or, AD0 high, 0x69 (WHO_AM_I, 0x75, reads 0x68 on both), wakes
 *   it and says "# mpu 0x68" (or 0x69, or "# no mpu") on a line; then "# baro 0x77" if an MS5611
 *   acknowledges its address.
 *   Every 10 ms (Timer2) it reads the accelerometer and keeps ESC pulses going (1000 us at 400 Hz on
 *   OC1A/OC1B of the 328P, PB1/PB2; OC3A/B/C of the 2560, PE3/PE4/PE5).
 *   MSP_ACC_CALIBRATION (205): stores the accelerometer's X, Y, Z now as 16-bit little-endian at EEPROM
 *   0-5 and 'C' at 6, replies $M> 0 205 with its checksum, and says "# acc calibrated" on a line.
 *   MSP_IDENT (100): replies with 7 bytes (version 240, type 3, MSP version 0, capability 0).
 *   Any other command: $M! 0 command (MultiWii's refusal). */
#include "uart0_115200.h"
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>
#include <util/twi.h>

static volatile uint8_t tick;
static uint8_t mpu;

ISR(TIMER2_COMPA_vect) { tick++; }

static void say(const char *s)
{
    while (*s)
        put((uint8_t)*s++);
    put('\r');
    put('\n');
}

static void reply(char direction, uint8_t command, const uint8_t *payload, uint8_t n)
{
    put('$');
    put('M');
    put((uint8_t)direction);
    put(n);
    put(command);
    uint8_t check = n ^ command;
    for (uint8_t i = 0; i < n; i++) {
        put(payload[i]);
        check ^= payload[i];
    }
    put(check);
}

static uint8_t twi(uint8_t control)
{
    TWCR = control | _BV(TWINT) | _BV(TWEN);
    while (!(TWCR & _BV(TWINT))) {
    }
    return TW_STATUS;
}

static void twi_stop(void)
{
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
    while (TWCR & _BV(TWSTO)) {
    }
}

/* reads n registers from reg; 0 when the chip did not acknowledge its address */
static uint8_t read_regs(uint8_t addr, uint8_t reg, uint8_t *out, uint8_t n)
{
    twi(_BV(TWSTA));
    TWDR = addr << 1;
    if (twi(0) != TW_MT_SLA_ACK) {
        twi_stop();
        return 0;
    }
    TWDR = reg;
    twi(0);
    twi(_BV(TWSTA));
    TWDR = addr << 1 | 1;
    twi(0);
    for (uint8_t i = 0; i < n; i++) {
        twi(i + 1 < n ? _BV(TWEA) : 0);
        out[i] = TWDR;
    }
    twi_stop();
    return 1;
}

static void write_reg(uint8_t addr, uint8_t reg, uint8_t value)
{
    twi(_BV(TWSTA));
    TWDR = addr << 1;
    twi(0);
    TWDR = reg;
    twi(0);
    TWDR = value;
    twi(0);
    twi_stop();
}

static uint8_t frame[40], frame_n;
static uint8_t accel[6];

static void command(uint8_t cmd)
{
    if (cmd == 205) {
        uint8_t saved[7] = { accel[1], accel[0], accel[3], accel[2], accel[5], accel[4], 'C' };
        eeprom_write_block(saved, (void *)0, sizeof saved);
        reply('>', 205, 0, 0);
        say("# acc calibrated");
    } else if (cmd == 100) {
        static const uint8_t ident[7] = { 240, 3, 0, 0, 0, 0, 0 };
        reply('>', 100, ident, sizeof ident);
    } else {
        reply('!', cmd, 0, 0);
    }
}

/* MSP v1 requests, $M< size command payload checksum */
static void msp_byte(uint8_t b)
{
    static const uint8_t head[3] = { '$', 'M', '<' };
    if (frame_n < 3) {
        frame_n = b == head[frame_n] ? frame_n + 1 : (b == '$');
        return;
    }
    frame[frame_n++ - 3] = b;
    uint8_t size = frame[0];
    if (size > 32) {
        frame_n = 0;
        return;
    }
    if (frame_n - 3 < size + 3)
        return;
    frame_n = 0;
    uint8_t check = 0;
    for (uint8_t i = 0; i < size + 2; i++)
        check ^= frame[i];
    if (check == frame[size + 2])
        command(frame[1]);
}

int main(void)
{
    uart0_init(_BV(RXEN0) | _BV(TXEN0));
    TWBR = 12; /* 400 kHz */
    uint8_t who = 0;
    if (read_regs(0x68, 0x75, &who, 1))
        mpu = 0x68;
    else if (read_regs(0x69, 0x75, &who, 1))
        mpu = 0x69;
    if (mpu) {
        write_reg(mpu, 0x6B, 0x00); /* awake */
        say(mpu == 0x68 ? "# mpu 0x68" : "# mpu 0x69");
    } else {
        say("# no mpu");
    }
    uint8_t prom[2];
    if (read_regs(0x77, 0xA2, prom, 2)) /* an MS5611's first calibration word */
        say("# baro 0x77");
#if defined(__AVR_ATmega2560__)
    DDRE |= _BV(3) | _BV(4) | _BV(5);
    ICR3 = 4999; /* 400 Hz at 2 MHz */
    OCR3A = OCR3B = OCR3C = 2000;
    TCCR3A = _BV(COM3A1) | _BV(COM3B1) | _BV(COM3C1) | _BV(WGM31);
    TCCR3B = _BV(WGM33) | _BV(WGM32) | _BV(CS31);
#else
    DDRB |= _BV(1) | _BV(2);
    ICR1 = 4999;
    OCR1A = OCR1B = 2000;
    TCCR1A = _BV(COM1A1) | _BV(COM1B1) | _BV(WGM11);
    TCCR1B = _BV(WGM13) | _BV(WGM12) | _BV(CS11);
#endif
    OCR2A = 249; /* 1 kHz at 250 kHz */
    TCCR2A = _BV(WGM21);
    TCCR2B = _BV(CS22);
    TIMSK2 = _BV(OCIE2A);
    sei();
    for (;;) {
        if (UCSR0A & _BV(RXC0))
            msp_byte(UDR0);
        if (tick >= 10) {
            tick = 0;
            if (mpu)
                read_regs(mpu, 0x3B, accel, sizeof accel);
        }
    }
}
