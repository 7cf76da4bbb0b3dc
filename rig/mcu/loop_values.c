/* The values of the abstract run (polling.h): known bytes, bytes of s*V + k, the flags of a subtraction
 * chain on V, and where they come from and go: registers, SREG, the stack pointer, the data space (a read
 * of a timer counter is V), the stores an iteration makes. Which branches these allow is decided here
 * too: a flag or a bit that is the same for every V the iterations read. */
#include <string.h>

#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>

#include "polling.h"

bool loop_fail(loop_run *x, const char *why)
{
    x->why = why;
    return false;
}

bool loop_out_of_range(loop_run *x, const char *why)
{
    x->range_limited = true;
    return loop_fail(x, why);
}

/* sign*V + k (sign: +1 or -1 for a timer counter, the step for an induction register) */
static uint32_t v_word(int8_t sign, uint32_t k, uint64_t v) { return k + (uint32_t)((int64_t)sign * (int64_t)v); }

static uint64_t step_size(int8_t sign) { return (uint64_t)(sign < 0 ? -(int)sign : sign); }

void loop_io_find(avr_t *avr, loop_io *io)
{
    memset(io, 0, sizeof *io);
    for (avr_io_t *port = avr->io_port; port; port = port->next) {
        if (!strcmp(port->kind, "timer") && io->n_timers < 8) {
            io->timer[io->n_timers] = (avr_timer_t *)port;
            io->timer_at[io->n_timers++] = ((avr_timer_t *)port)->r_tcnt;
        }
        if (!strcmp(port->kind, "uart") && io->n_plain < 22) {
            io->plain_at[io->n_plain++] = ((avr_uart_t *)port)->rxc.raised.reg;
            io->plain_at[io->n_plain++] = ((avr_uart_t *)port)->fe.reg;
        }
        if (!strcmp(port->kind, "port") && io->n_plain < 23)
            io->plain_at[io->n_plain++] = ((avr_ioport_t *)port)->r_pin;
    }
}

static avr_timer_t *timer_at(const loop_io *io, uint16_t addr)
{
    for (int i = 0; i < io->n_timers; i++)
        if (io->timer_at[i] == addr)
            return io->timer[i];
    return NULL;
}

static bool plain_read(const loop_io *io, uint16_t addr)
{
    for (int i = 0; i < io->n_plain; i++)
        if (io->plain_at[i] == addr)
            return true;
    return false;
}

uint64_t loop_v_at(const loop_run *x, uint64_t j)
{
    const avr_timer_t *p = x->timer;
    uint64_t t = x->start + j * x->t->period + x->v_offset;
    if (!p->tov_cycles || t < p->tov_base)
        return 0;
    return (t - p->tov_base) * ((uint32_t)p->tov_top + 1) / p->tov_cycles; /* (simavr's own formula) */
}

/* a chain's operands at V: the minuend and the subtrahend, n bits */
static void chain_operands(const loop_chain *c, uint64_t v, uint64_t *rd, uint64_t *rr, unsigned *n)
{
    *n = 8u * c->m;
    uint64_t mask = (1ull << *n) - 1;
    uint64_t a = v_word(c->sign, c->k, v) & mask, b = c->c & mask;
    *rd = c->v_is_rd ? a : b;
    *rr = c->v_is_rd ? b : a;
}

static bool chain_flag(const loop_chain *c, int which, uint64_t v)
{
    uint64_t rd, rr;
    unsigned n;
    chain_operands(c, v, &rd, &rr, &n);
    uint64_t r = (rd - rr) & ((1ull << n) - 1);
    bool neg = r >> (n - 1) & 1, ovf = ((rd ^ rr) & (rd ^ r)) >> (n - 1) & 1;
    uint8_t d8 = (uint8_t)(rd >> (n - 8)), r8 = (uint8_t)(rr >> (n - 8)), res8 = (uint8_t)(r >> (n - 8));
    switch (which) {
    case S_C:
        return rd < rr;
    case S_Z:
        return r == 0;
    case S_N:
        return neg;
    case S_V:
        return ovf;
    case S_S:
        return neg ^ ovf;
    default: /* S_H: the borrow from bit 3 of the last byte */
        return (((~d8 & r8) | (r8 & res8) | (res8 & ~d8)) >> 3) & 1;
    }
}

/* flag `which` of the chain is the same for every V in [lo, hi]: V's side moves through a range with no
 * point where it can change (Z: reaching the other side and leaving it; C: those and the wrap; N: those
 * and half a turn past them; V and S: all of these and the sign of V's side) */
static bool chain_constant(const loop_chain *c, int which, uint64_t lo, uint64_t hi)
{
    unsigned n = 8u * c->m;
    uint64_t mod = 1ull << n, mask = mod - 1, half = mod >> 1, b = c->c & mask;
    uint64_t a_min = v_word(c->sign, c->k, c->sign > 0 ? lo : hi) & mask;
    uint64_t a_max = a_min + step_size(c->sign) * (hi - lo);
    const uint64_t points[6] = { b, b + 1, 0, b + half, b + half + 1, half };
    int count = which == S_Z ? 2 : which == S_C ? 3 : which == S_N ? 5 : 6;
    for (int i = 0; i < count; i++) {
        if (which == S_N && i == 2) /* (N does not change at the wrap) */
            continue;
        uint64_t q = a_min + ((points[i] - a_min - 1) & mask) + 1; /* the first value past a_min that is it */
        if (q <= a_max)
            return false;
    }
    return true;
}

bool loop_flag_value(const loop_state *s, int which, uint64_t v)
{
    const loop_flag *f = &s->f[which];
    return f->kind == FLAG_CHAIN ? chain_flag(&s->chains[f->chain], which, v) : f->val;
}

uint8_t loop_byte_value(const loop_state *s, const loop_val *b, uint64_t v)
{
    if (b->sym)
        return (uint8_t)(v_word(b->sign, b->k, v) >> (8 * b->byte));
    uint8_t out = b->val;
    for (int i = 0; i < 8; i++)
        if (b->fsym >> i & 1 && chain_flag(&s->chains[b->chain], i, v))
            out |= (uint8_t)(1u << i);
    return out;
}

bool loop_flag_get(loop_run *x, int which, bool *out)
{
    const loop_flag *f = &x->s.f[which];
    if (f->kind == FLAG_KNOWN) {
        *out = f->val;
        return true;
    }
    if (f->kind == FLAG_UNKNOWN || which == S_H)
        return loop_fail(x, "a branch on an unknown flag");
    if (!chain_constant(&x->s.chains[f->chain], which, x->v_lo, x->v_hi))
        return loop_out_of_range(x, "a branch on a flag that changes");
    *out = chain_flag(&x->s.chains[f->chain], which, x->v_lo);
    return true;
}

bool loop_bit_get(loop_run *x, const loop_val *b, int bit, bool *out)
{
    if (b->sym) {
        unsigned g = 8u * b->byte + (unsigned)bit;
        uint64_t w_min = v_word(b->sign, b->k, b->sign > 0 ? x->v_lo : x->v_hi),
                 w_max = w_min + step_size(b->sign) * (x->v_hi - x->v_lo);
        if (w_min >> g != w_max >> g)
            return loop_out_of_range(x, "a bit test on a bit that changes");
        *out = w_min >> g & 1;
        return true;
    }
    if ((b->opq | b->fsym) >> bit & 1)
        return loop_fail(x, "a bit test on an unknown bit");
    *out = b->val >> bit & 1;
    return true;
}

void loop_set_flag(loop_run *x, int which, bool v) { x->s.f[which] = (loop_flag){ FLAG_KNOWN, v, 0 }; }
void loop_unknown_flag(loop_run *x, int which) { x->s.f[which] = (loop_flag){ FLAG_UNKNOWN, 0, 0 }; }

/* N, Z and S from a result, V given */
void loop_nzs(loop_run *x, uint8_t r, bool v)
{
    loop_set_flag(x, S_N, r >> 7);
    loop_set_flag(x, S_Z, r == 0);
    loop_set_flag(x, S_V, v);
    loop_set_flag(x, S_S, (r >> 7) ^ v);
}

bool loop_put(loop_run *x, uint16_t addr, loop_val v)
{
    loop_state *s = &x->s;
    for (int i = 0; i < s->n_stores; i++)
        if (s->store_at[i] == addr) {
            s->store[i] = v;
            return true;
        }
    if (s->n_stores >= LOOP_STORES)
        return loop_fail(x, "too many stores");
    s->store_at[s->n_stores] = addr;
    s->store[s->n_stores++] = v;
    return true;
}

static bool read_v(loop_run *x, avr_timer_t *tm, uint32_t offset, loop_val *out)
{
    if (x->counted)
        return loop_fail(x, "a timer counter read in a counted loop");
    if (x->read_v && x->timer != tm)
        return loop_fail(x, "two timer counters read");
    if (x->read_v && x->v_offset != offset)
        return loop_fail(x, "the timer counter read twice");
    if ((tm->ext_clock_flags & (AVR_TIMER_EXTCLK_FLAG_TN | AVR_TIMER_EXTCLK_FLAG_AS2)) &&
        !(tm->ext_clock_flags & AVR_TIMER_EXTCLK_FLAG_VIRT))
        return loop_fail(x, "a timer on an external clock");
    x->read_v = true;
    x->timer = tm;
    x->v_offset = offset;
    x->v_lo = loop_v_at(x, x->j_first);
    x->v_hi = loop_v_at(x, x->j_last);
    if (x->start + x->j_first * x->t->period + offset < tm->tov_base || x->v_hi > 0xFFFF)
        return loop_out_of_range(x, "the timer counter wraps");
    loop_val v = { .sym = true, .sign = 1 };
    *out = v;
    if (!loop_put(x, tm->r_tcnt, v)) /* (simavr keeps the count in data[], the high byte latched) */
        return false;
    v.byte = 1;
    return !tm->r_tcnth || loop_put(x, tm->r_tcnth, v);
}

bool loop_load(loop_run *x, uint16_t addr, uint32_t offset, loop_val *out)
{
    avr_t *avr = x->avr;
    loop_state *s = &x->s;
    if (addr < 32) {
        *out = s->r[addr];
        return true;
    }
    avr_timer_t *tm = timer_at(x->io, addr); /* (read again at each read, whatever was latched) */
    if (tm)
        return read_v(x, tm, offset, out);
    if (addr == R_SREG) {
        loop_val b = { 0 };
        int chain = -1;
        for (int i = 0; i < 8; i++) {
            const loop_flag *f = &s->f[i];
            if (f->kind == FLAG_KNOWN)
                b.val |= (uint8_t)(f->val << i);
            else if (f->kind == FLAG_UNKNOWN || (chain >= 0 && chain != f->chain))
                b.opq |= (uint8_t)(1u << i);
            else {
                chain = f->chain;
                b.fsym |= (uint8_t)(1u << i);
            }
        }
        b.chain = (uint8_t)(chain < 0 ? 0 : chain);
        *out = b;
        return true;
    }
    for (int i = 0; i < s->n_stores; i++)
        if (s->store_at[i] == addr) {
            *out = s->store[i];
            return true;
        }
    if (addr == R_SPL || addr == R_SPH) {
        *out = loop_known((uint8_t)(addr == R_SPL ? s->sp : s->sp >> 8));
        return true;
    }
    if (addr < 31 + MAX_IOs && avr->io[AVR_DATA_TO_IO(addr)].r.c) {
        if (!plain_read(x->io, addr))
            return loop_fail(x, "a read with side effects");
        *out = loop_known(avr->io[AVR_DATA_TO_IO(addr)].r.c(avr, addr, avr->io[AVR_DATA_TO_IO(addr)].r.param));
        return true;
    }
    if (addr > avr->ramend)
        return loop_fail(x, "a read outside the data space");
    *out = loop_known(avr->data[addr]);
    return true;
}

bool loop_store(loop_run *x, uint16_t addr, loop_val v)
{
    avr_t *avr = x->avr;
    if (addr < 32) {
        x->s.r[addr] = v;
        return true;
    }
    if (addr == R_SREG) {
        if (v.sym)
            return loop_fail(x, "SREG written from the timer counter");
        for (int i = 0; i < 8; i++)
            x->s.f[i] = (loop_flag){ v.opq >> i & 1    ? FLAG_UNKNOWN
                                     : v.fsym >> i & 1 ? FLAG_CHAIN
                                                       : FLAG_KNOWN,
                                     (uint8_t)(v.val >> i & 1), v.chain };
        return true;
    }
    if (addr <= avr->ioend || addr > avr->ramend)
        return loop_fail(x, "a store to an I/O register");
    return loop_put(x, addr, v);
}

bool loop_push(loop_run *x, loop_val v)
{
    if (!loop_store(x, x->s.sp, v))
        return false;
    x->s.sp--;
    return true;
}

bool loop_pop(loop_run *x, loop_val *v)
{
    x->s.sp++;
    return loop_load(x, x->s.sp, 0, v);
}

static bool same_chain(const loop_chain *a, const loop_chain *b)
{
    return a->sign == b->sign && a->m == b->m && a->v_is_rd == b->v_is_rd && a->k == b->k && a->c == b->c;
}

static bool same_val(const loop_state *a, const loop_state *b, const loop_val *x, const loop_val *y)
{
    if (x->sym != y->sym)
        return false;
    if (x->sym)
        return x->byte == y->byte && x->sign == y->sign && x->k == y->k;
    if (x->val != y->val || x->opq != y->opq || x->fsym != y->fsym)
        return false;
    return !x->fsym || same_chain(&a->chains[x->chain], &b->chains[y->chain]);
}

/* the two states have the same form: the same known bytes, the same functions of V */
bool loop_same(const loop_state *a, const loop_state *b)
{
    if (a->sp != b->sp || a->n_stores != b->n_stores)
        return false;
    for (int i = 0; i < 32; i++)
        if (!same_val(a, b, &a->r[i], &b->r[i]))
            return false;
    for (int i = 0; i < 8; i++) {
        const loop_flag *f = &a->f[i], *g = &b->f[i];
        if (f->kind != g->kind || (f->kind == FLAG_KNOWN && f->val != g->val) ||
            (f->kind == FLAG_CHAIN && !same_chain(&a->chains[f->chain], &b->chains[g->chain])))
            return false;
    }
    for (int i = 0; i < a->n_stores; i++)
        if (a->store_at[i] != b->store_at[i] || !same_val(a, b, &a->store[i], &b->store[i]))
            return false;
    return true;
}
