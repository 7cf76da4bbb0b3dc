/* The engine's lifecycle and run loop (glue.h): simavr 1.6 made safe to run a hostile image in the rig's
 * process, and run to a target cycle with every way a firmware can fail named. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/avr_eeprom.h>
#include <simavr/avr_extint.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_core.h>

#include "glue.h"

/* simavr indexes data[] with any 16-bit pointer (plus a displacement up to 63) and flash[] with any 24-bit
 * Z (ELPM, SPM) before or without checking it: buffers that large make a wild pointer harmless */
#define DATA_SPAN (0x10000 + 0x100)
#define FLASH_SPAN ((1u << 24) + 0x400)

uint64_t mcu_ns(const mcu_engine *e, uint64_t cycle)
{
    return cycle / e->clock_hz * 1000000000ull + cycle % e->clock_hz * 1000000000ull / e->clock_hz;
}

static uint64_t cycle_at(const mcu_engine *e, uint64_t t_ns) /* the first cycle at or after t_ns */
{
    uint64_t s = t_ns / 1000000000ull, rest = t_ns % 1000000000ull;
    return s * e->clock_hz + (rest * e->clock_hz + 999999999ull) / 1000000000ull;
}

static mcu_engine *engine_of(avr_t *avr) { return avr ? (mcu_engine *)avr->custom.data : NULL; }

/* simavr logs its errors (an invalid opcode, a bad data address) and goes on: the glue takes them as the
 * firmware's errors; the rest of its chatter is dropped */
static void logger(avr_t *avr, const int level, const char *format, va_list ap)
{
    mcu_engine *e = engine_of(avr);
    if (!e || level > LOG_ERROR || !strcmp(format, "%s\n")) /* (avr_sadly_crashed's own line) */
        return;
    vsnprintf(e->last_error, sizeof e->last_error, format, ap);
    for (char *c = e->last_error; *c; c++) /* drop the terminal's colour escapes and the newline */
        if (*c == '\033' || *c == '\n')
            *c = ' ';
    if (strstr(format, "Invalid Opcode") && !e->bad_opcode) {
        e->bad_opcode = true;
        e->bad_pc = avr->pc;
    }
}

static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr;
    (void)how_long;
}

static avr_cycle_count_t marker_fired(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    (void)when;
    (void)param;
    return 0;
}

/* simavr 1.6 re-arms a per-cycle poll of every INTx pin written low (level triggering) on each reset: off
 * (unless the bench asked for stock simavr, to measure what this saves) */
static void extint_fix(avr_t *avr)
{
    mcu_engine *e = engine_of(avr);
    for (uint8_t i = 0; i < 8; i++)
        avr_extint_set_strict_lvl_trig(avr, i, e && e->stock_extint);
}

/* the WDTON fuse: the watchdog always on in system reset mode, WDE never cleared. Set through simavr's
 * own WDTCSR handler with the timed sequence (WDCE and WDE, then WDE with the prescaler), so its timer
 * runs; a firmware's write that clears WDE is followed by the same sequence. */
#define WDTCSR 0x60
#define WDCE 0x10
#define WDE 0x08

static void wdton_arm(mcu_engine *e)
{
    avr_t *avr = e->avr;
    uint8_t wdp = avr->data[WDTCSR] & 0x27;
    e->wdt_write(avr, WDTCSR, WDCE | WDE, e->wdt_param);
    e->wdt_write(avr, WDTCSR, (uint8_t)(WDE | wdp), e->wdt_param);
}

static void wdtcsr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    mcu_engine *e = param;
    e->wdt_write(avr, addr, v, e->wdt_param);
    if (!(avr->data[WDTCSR] & WDE))
        wdton_arm(e);
}

/* the fuses the engine models (0: none) */
MCU_API void mcu_fuses(mcu_engine *e, bool watchdog_always_on)
{
    avr_t *avr = e->avr;
    int io = AVR_DATA_TO_IO(WDTCSR);
    if (!watchdog_always_on || e->wdton || !avr->io[io].w.c)
        return;
    e->wdton = true;
    e->wdt_write = avr->io[io].w.c;
    e->wdt_param = avr->io[io].w.param;
    avr->io[io].w.c = wdtcsr_write;
    avr->io[io].w.param = e;
    wdton_arm(e);
}

static void on_reset(avr_t *avr)
{
    mcu_engine *e = engine_of(avr);
    if (e->core_reset)
        e->core_reset(avr);
    e->reset_seen = true;
}

/* where the run must look at the firmware's hang and unanswered checks: the earliest of their deadlines
 * and the target (a glue event that starts a deadline calls it again) */
void mcu_deadline(mcu_engine *e)
{
    uint64_t to = e->target;
    if (e->hang_cycles && e->last_activity + e->hang_cycles < to)
        to = e->last_activity + e->hang_cycles;
    if (e->unanswered_cycles && e->twi.nack_since_cycle != MCU_NEVER &&
        e->twi.nack_since_cycle + e->unanswered_cycles < to)
        to = e->twi.nack_since_cycle + e->unanswered_cycles;
    e->stop_at = to;
}

void mcu_reschedule(mcu_engine *e)
{
    uint64_t next = e->twi.event ? e->twi.event_cycle : MCU_NEVER;
    uint64_t p = mcu_pwm_next(e), s = mcu_serial_next(e);
    next = p < next ? p : next;
    e->next_event = s < next ? s : next;
}

/* simavr's sleep jumps to its next cycle timer: one at our next event (or the target) keeps it from
 * passing it */
static void set_marker(mcu_engine *e, uint64_t target)
{
    uint64_t at = e->next_event < target ? e->next_event : target;
    if (at == e->marker)
        return;
    avr_cycle_timer_cancel(e->avr, marker_fired, e);
    e->marker = at;
    if (at != MCU_NEVER && at > e->avr->cycle)
        avr_cycle_timer_register(e->avr, at - e->avr->cycle, marker_fired, e);
}

MCU_API size_t mcu_engine_size(void) { return sizeof(mcu_engine); }

MCU_API void mcu_close(mcu_engine *e);

/* 0 or an error in err: the MCU unknown, the image too big */
MCU_API int mcu_open(mcu_engine *e, const char *mcu, uint32_t clock_hz, const uint8_t *image, uint32_t size,
                     const uint8_t *eeprom, uint32_t ee_size, char *err, size_t err_len)
{
    memset(e, 0, sizeof *e);
    avr_global_logger_set(logger);
    avr_t *avr = avr_make_mcu_by_name(mcu);
    if (!avr) {
        snprintf(err, err_len, "simavr has no MCU named %s", mcu);
        return -1;
    }
    if (size > avr->flashend + 1) {
        snprintf(err, err_len, "the image is %u bytes; the %s's flash is %u", size, mcu, avr->flashend + 1);
        free(avr);
        return -1;
    }
    avr_init(avr);
    avr->frequency = clock_hz;
    avr->vcc = avr->avcc = avr->aref = 5000; /* mV: a 5 V board (the ADC's AVCC reference) */
    avr->custom.data = e;
    avr->log = LOG_ERROR;
    e->avr = avr;
    e->clock_hz = clock_hz;
    e->code_end = size;
    uint8_t *data = calloc(1, DATA_SPAN), *flash = calloc(1, FLASH_SPAN);
    if (!data || !flash) {
        free(data);
        free(flash);
        snprintf(err, err_len, "out of memory");
        mcu_close(e);
        return -1;
    }
    memcpy(data, avr->data, avr->ramend + 1u);
    memcpy(flash, avr->flash, avr->flashend + 4u);
    free(avr->data);
    free(avr->flash);
    avr->data = data;
    avr->flash = flash;
    memcpy(avr->flash, image, size);
    if (eeprom && ee_size) {
        if (ee_size > avr->e2end + 1) {
            snprintf(err, err_len, "the EEPROM image is %u bytes; the %s's EEPROM is %u", ee_size, mcu, avr->e2end + 1);
            return -1;
        }
        avr_eeprom_desc_t d = { .ee = (uint8_t *)eeprom, .offset = 0, .size = ee_size };
        avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &d);
    }
    avr->sleep = no_sleep;
    e->core_reset = avr->reset;
    avr->reset = on_reset;
    extint_fix(avr);
    e->marker = MCU_NEVER;
    e->next_event = MCU_NEVER;
    e->watchdog_limit = 3;
    e->twi.nack_since_cycle = MCU_NEVER;
    mcu_twi_attach(e);
    mcu_pcint_attach(e);
    mcu_timer_modes_attach(e);
    return 0;
}

MCU_API void mcu_close(mcu_engine *e)
{
    avr_t *avr = e->avr;
    if (!avr)
        return;
    avr_terminate(avr);
    avr->custom.data = NULL;
    free(avr);
    free(e->twi.log);
    mcu_poll_free(e);
    free(e->timer_wraps);
    e->avr = NULL;
}

static int stopped(mcu_engine *e, int kind, uint32_t pc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->what, sizeof e->what, fmt, ap);
    va_end(ap);
    e->stop = kind;
    e->stop_pc = pc;
    e->stop_cycle = e->avr->cycle;
    return kind;
}

/* what simavr's state says after a step: 0 (runs on) or the stop */
static int check(mcu_engine *e)
{
    avr_t *avr = e->avr;
    if (e->bad_opcode)
        return stopped(e, MCU_CRASHED, e->bad_pc, "invalid opcode 0x%04x at pc 0x%05x",
                       avr->flash[e->bad_pc] | avr->flash[e->bad_pc + 1] << 8, e->bad_pc);
    if (avr->state == cpu_Crashed || avr->state == cpu_Stopped) {
        if (avr->pc >= avr->flashend)
            return stopped(e, MCU_CRASHED, avr->pc, "jump outside flash to 0x%05x", avr->pc);
        return stopped(e, MCU_CRASHED, avr->pc, "%s", e->last_error[0] ? e->last_error : "simavr stopped");
    }
    if (avr->state == cpu_Done)
        return stopped(e, MCU_SLEEPING, avr->pc, "sleep with interrupts off: it never wakes");
    if (e->reset_seen) {
        e->reset_seen = false;
        e->resets++;
        extint_fix(avr);
        mcu_twi_reset(e);
        mcu_pwm_reset(e);
        e->marker = MCU_NEVER; /* a reset clears simavr's cycle timers */
        if (e->wdton)
            wdton_arm(e);
        if (avr_regbit_get(avr, avr->reset_flags.wdrf)) {
            e->watchdog_resets++;
            if (e->watchdog_resets >= e->watchdog_limit)
                return stopped(e, MCU_WATCHDOG, avr->pc, "%u times", e->watchdog_resets);
        }
    }
    if (avr->pc >= e->code_end)
        return stopped(e, MCU_CRASHED, avr->pc, "jump outside the program (%u bytes) to 0x%05x", e->code_end, avr->pc);
    return 0;
}

/* runs to e->stop_at (which a glue event may bring nearer) or an earlier stop */
static int run_to(mcu_engine *e)
{
    avr_t *avr = e->avr;
    uint32_t code_end = e->code_end;
    set_marker(e, e->stop_at);
    for (;;) {
        if (avr->cycle >= e->next_event) {
            if (e->twi.event && avr->cycle >= e->twi.event_cycle) {
                int r = mcu_twi_event(e);
                if (r)
                    return r;
            }
            mcu_pwm_event(e);
            mcu_serial_event(e);
            mcu_reschedule(e);
            set_marker(e, e->stop_at);
        }
        if (avr->cycle >= e->stop_at)
            return MCU_REACHED;
        uint32_t pc_before = avr->pc;
        int state = avr_run(avr);
        e->instructions++;
        if (e->poll && (avr->pc < pc_before || e->poll_watch))
            mcu_poll_step(e, pc_before);
        if (e->next_event < e->marker) /* an instruction started a glue event: a sleep may not pass it */
            set_marker(e, e->stop_at);
        if (state != cpu_Running || avr->pc >= code_end || e->bad_opcode || e->reset_seen) {
            if (state == cpu_Sleeping && avr->pc < code_end && !e->bad_opcode && !e->reset_seen)
                continue;
            int r = check(e);
            if (r)
                return r;
            set_marker(e, e->stop_at);
        }
    }
}

/* Runs to target_cycle or an earlier stop (MCU_*). A stop other than MCU_NEED and MCU_REACHED is final:
 * the firmware's error, at the cycle it became one (a hang when it has lasted hang_cycles). */
MCU_API int mcu_run(mcu_engine *e, uint64_t target_cycle)
{
    avr_t *avr = e->avr;
    if (e->stop != MCU_REACHED && e->stop != MCU_NEED)
        return e->stop;
    e->stop = MCU_REACHED;
    for (;;) {
        e->target = target_cycle;
        mcu_deadline(e);
        int r = run_to(e);
        if (r == MCU_NEED)
            return e->stop = MCU_NEED;
        if (r)
            return r;
        if (e->hang_cycles && avr->cycle - e->last_activity >= e->hang_cycles)
            return stopped(e, MCU_HUNG, avr->pc,
                           "no TWI transaction, motor pulse, USART byte sent or output pin change for %llu ms",
                           (unsigned long long)(mcu_ns(e, e->hang_cycles) / 1000000u));
        if (e->unanswered_cycles && e->twi.nack_since_cycle != MCU_NEVER &&
            avr->cycle - e->twi.nack_since_cycle >= e->unanswered_cycles && e->twi.nacks_in_row >= 2)
            return stopped(e, MCU_UNANSWERED, avr->pc, "%u addresses in a row not acknowledged over %llu ms",
                           e->twi.nacks_in_row, (unsigned long long)(mcu_ns(e, e->unanswered_cycles) / 1000000u));
        if (avr->cycle >= target_cycle)
            return MCU_REACHED;
    }
}

MCU_API uint64_t mcu_cycle_at(const mcu_engine *e, uint64_t t_ns) { return cycle_at(e, t_ns); }
MCU_API uint64_t mcu_ns_at(const mcu_engine *e, uint64_t cycle) { return mcu_ns(e, cycle); }
MCU_API uint64_t mcu_cycle(const mcu_engine *e) { return e->avr->cycle; }
MCU_API uint32_t mcu_pc(const mcu_engine *e) { return e->avr->pc; }
MCU_API const char *mcu_what(const mcu_engine *e) { return e->what; }
MCU_API uint32_t mcu_stop_pc(const mcu_engine *e) { return e->stop_pc; }
MCU_API uint64_t mcu_stop_cycle(const mcu_engine *e) { return e->stop_cycle; }
MCU_API void mcu_need(const mcu_engine *e, chip_need *out) { *out = e->need; }

MCU_API void mcu_limits(mcu_engine *e, uint32_t watchdog_resets, uint64_t hang_ns, uint64_t unanswered_ns)
{
    e->watchdog_limit = watchdog_resets;
    e->hang_cycles = hang_ns ? cycle_at(e, hang_ns) : 0;
    e->unanswered_cycles = unanswered_ns ? cycle_at(e, unanswered_ns) : 0;
}

MCU_API void mcu_attach_chips(mcu_engine *e, chip_board *board, const mcu_chip_calls *calls)
{
    e->board = board;
    e->chip = *calls;
}

/* the figures engine.py reports: counters by index (engine.py FIGURES) */
MCU_API uint64_t mcu_figure(const mcu_engine *e, int which)
{
    const mcu_twi *t = &e->twi;
    switch (which) {
    case 0:
        return e->avr->cycle;
    case 1:
        return e->instructions;
    case 2:
        return t->transactions;
    case 3:
        return t->bytes;
    case 4:
        return t->nacks;
    case 5:
        return t->collisions;
    case 6:
        return e->resets;
    case 7:
        return e->watchdog_resets;
    case 8:
        return e->avr->pc;
    case 9:
        return e->avr->data[R_SPL] | e->avr->data[R_SPH] << 8;
    case 10:
        return t->data_nacks;
    case 11:
        return t->ignored;
    case 12:
        return t->abandoned;
    case 13:
        return t->bus_errors;
    case 14:
        return t->arbitration_lost;
    default:
        return 0;
    }
}

/* bench/mcu_rates.py only: simavr's own behaviour back (1: the INTx level poll, 2: the UART poll sleep,
 * 4: the timer modes it lacks run with TOP 0) */
MCU_API void mcu_stock(mcu_engine *e, int which)
{
    e->stock_extint = which & 1;
    extint_fix(e->avr);
    mcu_timer_modes_stock(e, which & 4);
    if (which & 2) {
        uint32_t flags = AVR_UART_FLAG_POLL_SLEEP;
        for (char n = '0'; n <= '3'; n++)
            avr_ioctl(e->avr, AVR_IOCTL_UART_SET_FLAGS(n), &flags);
    }
}

/* a byte of the data space; SREG as its flags are (simavr keeps them apart and its data[] copy is only
 * brought up to date when the firmware reads or writes SREG) */
MCU_API uint8_t mcu_peek(const mcu_engine *e, uint16_t addr)
{
    if (addr != R_SREG)
        return e->avr->data[addr];
    uint8_t sreg = 0;
    for (int i = 0; i < 8; i++)
        sreg |= (uint8_t)((e->avr->sreg[i] ? 1u : 0u) << i);
    return sreg;
}

/* the EEPROM as the firmware left it, up to max bytes into out; returns how many (the MCU's EEPROM size,
 * or less when max is; 0 when simavr would not give it) */
MCU_API uint32_t mcu_eeprom_read(mcu_engine *e, uint8_t *out, uint32_t max)
{
    uint32_t size = e->avr->e2end + 1u < max ? e->avr->e2end + 1u : max;
    /* (asked with no buffer, simavr 1.6 points ee at its own; its GET returns -1 even when it worked) */
    avr_eeprom_desc_t d = { .ee = NULL, .offset = 0, .size = size };
    avr_ioctl(e->avr, AVR_IOCTL_EEPROM_GET, &d);
    if (!size || !d.ee)
        return 0;
    memcpy(out, d.ee, size);
    return size;
}
