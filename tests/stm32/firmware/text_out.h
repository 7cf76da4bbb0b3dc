/* What the RC test firmwares (ppm_rx.c, pwm_rx.c) say of a frame of channel widths: text lines out on
   USART6 TX (the STM32F405 board's telemetry port, byte by byte as TXE allows), which the MCU session
   keeps as telemetry, and "NAME_F_C=0xWIDTH" lines through semihosting (a firmware that sends other
   lines uses the first two alone). */
#ifndef TEXT_OUT_H
#define TEXT_OUT_H

#include "semihost.h"
#include "stm32f405.h"

static void usart6_text(const char *s)
{
    for (; *s; s++) {
        while (!(USART_SR(USART6_BASE) & USART_SR_TXE)) {
        }
        USART_DR(USART6_BASE) = (uint8_t)*s;
    }
}

/* " 1234" (a space, then @value in decimal) at @out, returning the end */
static char *decimal(char *out, uint32_t value)
{
    char digits[10];
    unsigned n = 0;
    do {
        digits[n++] = (char)('0' + value % 10u);
        value /= 10u;
    } while (value);
    *out++ = ' ';
    while (n) {
        *out++ = digits[--n];
    }
    return out;
}

/* "NAME w1 w2 ... wN\n" on USART6 */
__attribute__((unused)) static void send_widths(const char *name, const uint32_t *w, unsigned n)
{
    char line[8 + 8u * 11u + 2u];
    char *end = line;
    while (*name && end < line + 8) {
        *end++ = *name++;
    }
    for (unsigned c = 0; c < n && c < 8u; c++) {
        end = decimal(end, w[c]);
    }
    *end++ = '\n';
    *end = '\0';
    usart6_text(line);
}

/* Frame @f's @n widths (at most 9) through semihosting: "ppm_F_C=0x..." for @prefix "ppm" */
__attribute__((unused)) static void report_widths(const char *prefix, unsigned f, const uint32_t *w, unsigned n)
{
    char name[16];
    unsigned k = 0;
    while (*prefix && k < 10u) {
        name[k++] = *prefix++;
    }
    name[k++] = '_';
    name[k++] = (char)('0' + f % 10u);
    name[k++] = '_';
    name[k + 1] = '\0';
    for (unsigned c = 0; c < n && c < 9u; c++) {
        name[k] = (char)('1' + c);
        report(name, w[c]);
    }
}

#endif
