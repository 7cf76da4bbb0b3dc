/* The polling-loop skip (polling.c, loop_eval.c; docs/mcu.md "Polling loops"): a short loop that waits on
 * a flag, a timer counter or the cycle counter is proved, from the firmware's own instructions, to spin the
 * same way until the next thing that can change what it reads (a simavr cycle timer, a glue event, the
 * run's target); the engine's clock then jumps over whole iterations, leaving every register, flag and
 * byte of memory as running them would have.
 *
 * The proof is an abstract run of one iteration: every value is a known byte, or a byte of s*V + k where V
 * is the timer counter the iteration reads (s = +1 or -1), or unknown (a value of the iteration before,
 * which may only be moved). Each branch must go the same way for every V the skipped iterations read, and
 * the state at the loop's head after an iteration must have the same form as before it.
 *
 * A counted loop (an induction register: a byte stepped by the same amount each iteration, a wait with a
 * time-out such as MultiWii's for TWINT) reads no timer counter: V is then the iteration's number j and
 * the register s*j + k, s its step; it must have the form k + s*(j+1) after iteration j. */
#ifndef RIG_MCU_POLLING_H
#define RIG_MCU_POLLING_H

#include <stdbool.h>
#include <stdint.h>

#include <simavr/avr_timer.h>

#include "glue.h"

#define LOOP_TRACE 128 /* instructions an iteration may have */
#define LOOP_STORES 48 /* bytes of memory an iteration may write */
#define LOOP_CHAINS 16 /* subtractions on V an iteration may start */

/* a byte: known bits (val), unknown bits (opq), flags of a chain (fsym: bits of an SREG image); or, when
 * sym, byte `byte` of sign*V + k */
typedef struct {
    bool sym;
    uint8_t val, opq, fsym, chain, byte;
    int8_t sign;
    uint32_t k;
} loop_val;

/* a multi-byte subtraction with V on one side: bytes 0..m-1 of (sign*V + k) against c's (v_is_rd: V's
 * side is the minuend) */
typedef struct {
    int8_t sign;
    uint8_t m;
    bool v_is_rd;
    uint32_t k, c;
} loop_chain;

enum { FLAG_KNOWN, FLAG_CHAIN, FLAG_UNKNOWN };

typedef struct {
    uint8_t kind, val, chain;
} loop_flag;

typedef struct {
    loop_val r[32];
    loop_flag f[8];
    uint16_t sp;
    uint8_t n_stores, n_chains;
    uint16_t store_at[LOOP_STORES];
    loop_val store[LOOP_STORES];
    loop_chain chains[LOOP_CHAINS];
} loop_state;

/* one iteration as it ran: each instruction's address and the cycle it ended at */
typedef struct {
    uint32_t head;
    uint16_t n;
    uint32_t period;
    uint32_t pc[LOOP_TRACE];
    uint64_t end[LOOP_TRACE];
} loop_trace;

/* the I/O registers a loop may read that simavr computes when read: the timer counters (TCNTn, low byte,
 * V), and those whose read only recomputes a value from what the window keeps: the USARTs' status
 * registers (FE from the input queue) and the ports' PINx (the driven pins and the outputs) */
typedef struct {
    uint8_t n_timers, n_plain;
    uint16_t timer_at[8], plain_at[24];
    avr_timer_t *timer[8];
} loop_io;

/* an abstract run of one iteration from s, for the iterations j_first..j_last after the one starting at
 * cycle start */
typedef struct {
    avr_t *avr;
    const loop_io *io;
    const loop_trace *t;
    uint64_t start;
    uint64_t j_first, j_last;
    bool counted; /* V is the iteration's number (a counted loop), not a timer counter */
    loop_state s;
    bool read_v;
    uint32_t v_offset; /* the cycle of V's read in the iteration */
    uint64_t v_lo, v_hi;
    avr_timer_t *timer; /* V's */
    const char *why;    /* why it failed */
    uint32_t fail_pc;
    bool range_limited; /* it failed on the counter's range: a smaller one may prove */
} loop_run;

static inline loop_val loop_known(uint8_t v) { return (loop_val){ .val = v }; }
static inline bool loop_is_known(const loop_val *b) { return !b->sym && !b->opq && !b->fsym; }

/* loop_eval.c */
bool loop_eval(loop_run *x);
/* loop_values.c */
bool loop_fail(loop_run *x, const char *why);
bool loop_out_of_range(loop_run *x, const char *why);
bool loop_flag_get(loop_run *x, int which, bool *out);
bool loop_bit_get(loop_run *x, const loop_val *b, int bit, bool *out);
void loop_set_flag(loop_run *x, int which, bool v);
void loop_unknown_flag(loop_run *x, int which);
void loop_nzs(loop_run *x, uint8_t r, bool v);
bool loop_put(loop_run *x, uint16_t addr, loop_val v);
bool loop_load(loop_run *x, uint16_t addr, uint32_t offset, loop_val *out);
bool loop_store(loop_run *x, uint16_t addr, loop_val v);
bool loop_push(loop_run *x, loop_val v);
bool loop_pop(loop_run *x, loop_val *v);
uint64_t loop_v_at(const loop_run *x, uint64_t j);
bool loop_flag_value(const loop_state *s, int which, uint64_t v);
uint8_t loop_byte_value(const loop_state *s, const loop_val *b, uint64_t v);
bool loop_same(const loop_state *a, const loop_state *b);
void loop_io_find(avr_t *avr, loop_io *io);

#endif
