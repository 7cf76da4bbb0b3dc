/* The I2C replayer for the STM32F405, the AVR's twi_replay.c on I2C1: runs one recorded client trace
   (emulators/traces, the table generated into traces.h by tests/mcu/gen_traces.py) through I2C1 at
   381 kHz with ST's HAL polling sequences (i2c_hal_poll.h), each step at its time since the start, so
   tests/stm32/test_i2c_replay.py can hold the bus's bytes against lockstep's. Which trace: the first byte
   of the .fc_config section, where the link writes a settings image (Stm32Config.settings), as the AVR
   firmware takes EEPROM byte 0. A step is one transfer: a write, a read, a write then a read with a
   repeated START (HAL_I2C_Mem_Read), or an address alone (HAL_I2C_IsDeviceReady); an address not
   acknowledged sends STOP and ends the step. Per step it reports "step=N:HEX" through semihosting, N 1
   when an address was NACKed, HEX the bytes read; "done" at the end. Between steps the core sleeps in
   WFI until SysTick says the next is due: a polling core costs QEMU an MMIO access per loop. */
#include "i2c_hal_poll.h"

#define PROGMEM /* traces.h is written for the AVR's flash */
#include "traces.h"

#define HCLK_MHZ 16u /* HSI: DWT_CYCCNT counts 16 a microsecond */
#define SYST_ENABLE_TICKINT_CPU 0x7u
#define SYST_MAX_RELOAD 0x00FFFFFFu
#define MAX_READ 255u /* a step's read is one message, its length a byte */

/* The settings image's first byte: the trace's index (0xFF, erased flash, or out of range: the first).
   Read-only, so the linker keeps the section in flash (as flash_prog.c's); read through a volatile
   pointer, as the link changes it after the build */
__attribute__((section(".fc_config"), used)) static const uint8_t settings[4] = { 0xFF, 0xFF, 0xFF, 0xFF };

void systick_handler(void) {}

/* Sleeps until DWT_CYCCNT reaches @due: SysTick wakes the core at most 2^24 cycles later each time */
static void sleep_until(uint32_t due)
{
    for (;;) {
        int32_t left = (int32_t)(due - DWT_CYCCNT);
        if (left <= 0) {
            return;
        }
        SYST_RVR = (uint32_t)left - 1u < SYST_MAX_RELOAD ? (uint32_t)left - 1u : SYST_MAX_RELOAD;
        SYST_CVR = 0;
        SYST_CSR = SYST_ENABLE_TICKINT_CPU;
        __asm volatile("wfi");
        SYST_CSR = 0;
    }
}

/* "step=N:HEX", N the NACK flag */
static void report_step(int nacked, const uint8_t *rx, unsigned n)
{
    static char line[8 + 2 * MAX_READ + 2];
    unsigned k = 0;
    for (const char *p = "step="; *p; p++) {
        line[k++] = *p;
    }
    line[k++] = nacked ? '1' : '0';
    line[k++] = ':';
    for (unsigned i = 0; i < n; i++) {
        line[k++] = "0123456789abcdef"[rx[i] >> 4];
        line[k++] = "0123456789abcdef"[rx[i] & 0xFu];
    }
    line[k++] = '\n';
    line[k] = '\0';
    put_text(line);
}

/* One message of a step: address, 1 for a read, length, a write's bytes */
struct msg {
    uint8_t addr, read, len;
    const uint8_t *data;
};

static const uint8_t *parse_msg(const uint8_t *p, struct msg *m)
{
    m->addr = p[0];
    m->read = p[1];
    m->len = p[2];
    m->data = p + 3;
    return p + 3 + (m->read ? 0u : m->len);
}

/* The step's transfer, its read bytes in @rx (their count in @n_rx): 0, or -1 on a NACK. A shape the
   HAL's sequences do not make (two writes, a read then anything, a read of nothing) ends the run. */
static int transfer(const struct msg *m, unsigned n, uint8_t *rx, unsigned *n_rx)
{
    *n_rx = 0;
    if (n == 1 && !m[0].read && m[0].len == 0) {
        return probe(m[0].addr);
    }
    if (n == 1 && !m[0].read) {
        return xfer(m[0].addr, m[0].data, m[0].len, 0, 0);
    }
    const struct msg *r = &m[n - 1];
    int shape = r->read && r->len > 0 && (n == 1 || (n == 2 && !m[0].read && m[0].len > 0 && m[0].addr == r->addr));
    if (!shape) {
        report("unsupported_step", n);
        exit_with(5);
    }
    int result = n == 1 ? xfer(r->addr, 0, 0, rx, r->len) : xfer(r->addr, m[0].data, m[0].len, rx, r->len);
    *n_rx = result == 0 ? r->len : 0;
    return result;
}

int main(void)
{
    i2c1_init(I2C_CCR_FS | 14u, 6u); /* 16 MHz / (3 * 14): 381 kHz; 300 ns rise: 16 * 0.3 + 1 */
    DWT_CTRL |= 1u;                  /* CYCCNTENA */
    uint8_t which = *(const volatile uint8_t *)settings;
    which = which < TRACE_COUNT ? which : 0u;
    const uint8_t *p = trace_data + trace_offset[which];
    uint32_t due = DWT_CYCCNT;
    for (;;) {
        uint32_t dt_us = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
        uint8_t n = p[4];
        p += 5;
        if (n == 0xFF) {
            break;
        }
        struct msg m[4];
        if (n > 4) {
            report("unsupported_step", n);
            exit_with(5);
        }
        for (unsigned i = 0; i < n; i++) {
            p = parse_msg(p, &m[i]);
        }
        due += dt_us * HCLK_MHZ;
        sleep_until(due);
        static uint8_t rx[MAX_READ];
        unsigned n_rx;
        int result = transfer(m, n, rx, &n_rx);
        report_step(result != 0, rx, n_rx);
    }
    wait_bus_free();
    put_text("done\n");
    return 0;
}
