/* What the STM32 tier's test firmwares report with: ARM semihosting (QEMU's -semihosting-config
   enable=on): lines of text on QEMU's standard output and the exit status. */
#ifndef SEMIHOST_H
#define SEMIHOST_H

#include <stdint.h>

#define SYS_WRITE0 0x04u
#define SYS_EXIT_EXTENDED 0x20u
#define ADP_STOPPED_APPLICATION_EXIT 0x20026u

static inline uint32_t semihost(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm("r0") = op;
    register const void *r1 __asm("r1") = arg;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

static inline void put_text(const char *text) { semihost(SYS_WRITE0, text); }

/* Ends the run: QEMU exits with @status */
static inline void exit_with(uint32_t status)
{
    const uint32_t block[2] = { ADP_STOPPED_APPLICATION_EXIT, status };
    semihost(SYS_EXIT_EXTENDED, block);
    for (;;) {
    }
}

/* One line "NAME=0xXXXXXXXX" */
static inline void report(const char *name, uint32_t value)
{
    char line[64];
    unsigned n = 0;
    while (*name && n < sizeof line - 13) {
        line[n++] = *name++;
    }
    line[n++] = '=';
    line[n++] = '0';
    line[n++] = 'x';
    for (int shift = 28; shift >= 0; shift -= 4) {
        line[n++] = "0123456789abcdef"[(value >> shift) & 0xFu];
    }
    line[n++] = '\n';
    line[n] = '\0';
    put_text(line);
}

#endif
