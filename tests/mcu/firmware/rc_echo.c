/* The RC echo: takes the three RC inputs of the MCU tier and sends back what it decoded, so the tests can
 * see each input arrive whole and on time.
 *   SBUS: 25-byte frames at 100000 baud 8E2 (USART1 on the ATmega2560, USART0 on the ATmega328P);
 *   MSP v1 SET_RAW_RC (200) at 115200 8N1 on USART0 (ATmega2560 only: the 328P has one USART);
 *   a PPM sum on INT0 (PD2) of the 328P, INT4 (PE4) of the 2560, rising edges timed by Timer1 at 2 MHz.
 * Each decoded frame goes out on USART0 as 0xE0 + source (0 SBUS, 1 MSP, 2 PPM), the channel count, the
 * channels as 16-bit little-endian (SBUS raw 11-bit values, MSP and PPM microseconds). On the 328P the
 * echo shares USART0 with SBUS, at SBUS's frame. */
#include "uart0_115200.h"
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#if defined(__AVR_ATmega2560__)
#define SBUS_UDR UDR1
#define SBUS_A UCSR1A
#define SBUS_B UCSR1B
#define SBUS_C UCSR1C
#define SBUS_UBRR UBRR1
#define SBUS_RXC RXC1
#define SBUS_FE FE1
#define SBUS_UPE UPE1
#define HAS_MSP 1
#else
#define SBUS_UDR UDR0
#define SBUS_A UCSR0A
#define SBUS_B UCSR0B
#define SBUS_C UCSR0C
#define SBUS_UBRR UBRR0
#define SBUS_RXC RXC0
#define SBUS_FE FE0
#define SBUS_UPE UPE0
#define HAS_MSP 0
#endif

static volatile uint16_t ppm[12];
static volatile uint8_t ppm_n, ppm_ready, ppm_index;
static volatile uint16_t ppm_last;

static void ppm_edge(void)
{
    uint16_t now = TCNT1;
    uint16_t width = (uint16_t)(now - ppm_last);
    ppm_last = now;
    if (width > 2 * 3000) { /* the sync gap: a frame ended */
        if (ppm_index) {
            ppm_n = ppm_index;
            ppm_ready = 1;
        }
        ppm_index = 0;
    } else if (ppm_index < 12) {
        ppm[ppm_index++] = width / 2;
    }
}

#if defined(__AVR_ATmega2560__)
ISR(INT4_vect) { ppm_edge(); }
#else
ISR(INT0_vect) { ppm_edge(); }
#endif

static void echo(uint8_t source, const uint16_t *ch, uint8_t n)
{
    put(0xE0 + source);
    put(n);
    for (uint8_t i = 0; i < n; i++) {
        put(ch[i] & 0xFF);
        put(ch[i] >> 8);
    }
}

static uint8_t sbus[25], sbus_n;

static void sbus_byte(uint8_t b)
{
    if (sbus_n == 0 && b != 0x0F)
        return;
    sbus[sbus_n++] = b;
    if (sbus_n < 25)
        return;
    sbus_n = 0;
    uint16_t ch[16];
    uint32_t bits = 0;
    uint8_t have = 0, k = 1;
    for (uint8_t i = 0; i < 16; i++) {
        while (have < 11) {
            bits |= (uint32_t)sbus[k++] << have;
            have += 8;
        }
        ch[i] = bits & 0x7FF;
        bits >>= 11;
        have -= 11;
    }
    echo(0, ch, 16);
}

#if HAS_MSP
static uint8_t msp[64], msp_n;

static void msp_byte(uint8_t b)
{
    static const uint8_t head[3] = { '$', 'M', '<' };
    if (msp_n < 3) {
        msp_n = b == head[msp_n] ? msp_n + 1 : (b == '$');
        return;
    }
    msp[msp_n++ - 3] = b;
    uint8_t len = msp[0];
    if (len > 32) {
        msp_n = 0;
        return;
    }
    if (msp_n - 3 < len + 3)
        return;
    msp_n = 0;
    uint8_t sum = 0;
    for (uint8_t i = 0; i < len + 2; i++)
        sum ^= msp[i];
    if (sum != msp[len + 2] || msp[1] != 200)
        return;
    uint16_t ch[16];
    for (uint8_t i = 0; i < len / 2; i++)
        ch[i] = msp[2 + 2 * i] | msp[3 + 2 * i] << 8;
    echo(1, ch, len / 2);
}
#endif

int main(void)
{
    SBUS_UBRR = 9; /* 100000 baud: 16 MHz / 16 / 10 */
    SBUS_C = _BV(UPM01) | _BV(USBS0) | _BV(UCSZ01) | _BV(UCSZ00);
    SBUS_B = _BV(RXEN0) | _BV(TXEN0);
#if HAS_MSP
    uart0_init(_BV(RXEN0) | _BV(TXEN0));
    EICRB = _BV(ISC41) | _BV(ISC40);
    EIMSK = _BV(INT4);
#else
    EICRA = _BV(ISC01) | _BV(ISC00);
    EIMSK = _BV(INT0);
#endif
    TCCR1B = _BV(CS11);
    sei();
    for (;;) {
        if (SBUS_A & _BV(SBUS_RXC)) {
            uint8_t bad = SBUS_A & (_BV(SBUS_FE) | _BV(SBUS_UPE));
            uint8_t b = SBUS_UDR;
            if (!bad)
                sbus_byte(b);
        }
#if HAS_MSP
        if (UCSR0A & _BV(RXC0))
            msp_byte(UDR0);
#endif
        if (ppm_ready) {
            uint16_t ch[12];
            cli();
            uint8_t n = ppm_n;
            for (uint8_t i = 0; i < n; i++)
                ch[i] = ppm[i];
            ppm_ready = 0;
            sei();
            echo(2, ch, n);
        }
    }
}
