/* The polling-loop skip's driver (polling.h): finds loops, records one iteration as it runs, proves the
 * iterations up to the next thing that can change what the loop reads, runs one of them for real to check
 * the proof's prediction, and jumps the clock over the rest.
 *
 * A loop head is an address a backward jump (or a return) reaches twice within LOOP_CLOSE cycles. Its
 * iteration is recorded once (each instruction's address and the cycle it ended at: the period, and
 * when in it the timer counter is read, are simavr's own). At the head, with no interrupt pending:
 *  1. the window: the earliest of simavr's next cycle timer (the timers' compare and overflow, the
 *     glue's marker), the glue's next event and the run's stop; nothing the loop reads changes before it;
 *  2. the abstract run of the next iteration (iteration 0) from the real state, giving its end state E1
 *     (each byte known or a function of what the timer counter reads);
 *  3. the abstract run of iterations 1..m from E1 with its V-dependent bytes unknown: every branch the
 *     same for every counter value those iterations read, the end state E1's form again (so by
 *     induction every iteration up to m does the same);
 *  4. iteration 0 runs for real; at the head again, the machine must be E1 at iteration 0's counter
 *     value, byte for byte (else the loop is never skipped again: the proof and simavr disagree);
 *  5. the clock jumps m periods and the machine becomes E1's form at iteration m's counter value: the
 *     registers, flags and stores iteration m leaves, as running the m iterations would.
 * A counted loop (polling.h) proves iterations 1..m with its counters k + s*j instead of E1's bytes.
 * The instructions figure counts the skipped iterations' instructions: the same figures either way. */
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/sim_interrupts.h>

#include "polling.h"

#define LOOPS 64
#define SEEN 256
#define LOOP_CLOSE 1024 /* cycles */
#define MIN_SKIP 3      /* iterations: fewer is not worth the proof */
#define BACK_OFF 16     /* a loop that failed is tried again after up to 2^16 of its periods */

typedef struct {
    /* (first: what each backward jump looks at, in the cache line of the trace's head) */
    bool have, dead; /* (dead: a prediction simavr did not confirm) */
    bool counted;    /* a counted loop last time, with these counters' steps */
    uint16_t fails;
    uint64_t retry_at; /* the cycle before which it is not tried (after a failure) */
    uint64_t seen;     /* the last cycle it was reached at */
    loop_trace t;
    int8_t step[32];
} loop_head;

struct mcu_poll {
    struct {
        uint32_t pc;
        uint64_t cycle;
        loop_head *head; /* (its entry, or NULL) */
    } seen[SEEN];
    loop_io io;
    loop_head loops[LOOPS];
    uint8_t n_loops;
    loop_head *rec;
    uint64_t rec_begin;
    loop_head *armed;
    uint64_t armed_start, armed_m, v0, vm;
    uint16_t armed_n;
    int8_t armed_istate;
    uint32_t armed_resets;
    loop_state e1, e2;
    uint64_t skipped, skips, refused, mismatches;
};

MCU_API void mcu_poll_enable(mcu_engine *e, bool on)
{
    if (on && !e->poll) {
        e->poll = calloc(1, sizeof *e->poll);
        if (e->poll)
            loop_io_find(e->avr, &e->poll->io);
    }
    if (!on)
        mcu_poll_free(e);
}

void mcu_poll_free(mcu_engine *e)
{
    free(e->poll);
    e->poll = NULL;
    e->poll_watch = false;
}

/* 0 cycles skipped, 1 skips, 2 loops proved and skipped at least once... (engine.py POLL_FIGURES) */
MCU_API uint64_t mcu_poll_figure(const mcu_engine *e, int which)
{
    const mcu_poll *p = e->poll;
    if (!p)
        return 0;
    switch (which) {
    case 0:
        return p->skipped;
    case 1:
        return p->skips;
    case 2:
        return p->refused;
    case 3:
        return p->mismatches;
    default:
        return 0;
    }
}

static void state_from_avr(loop_state *s, const avr_t *avr)
{
    for (int i = 0; i < 32; i++)
        s->r[i] = loop_known(avr->data[i]);
    for (int i = 0; i < 8; i++)
        s->f[i] = (loop_flag){ FLAG_KNOWN, avr->sreg[i], 0 };
    s->sp = (uint16_t)(avr->data[R_SPL] | avr->data[R_SPH] << 8);
    s->n_stores = s->n_chains = 0;
}

/* the parts of a state in use (most of one is room for stores and chains: a copy of all of it cost as
 * much as the proof) */
static void copy_state(loop_state *to, const loop_state *from)
{
    memcpy(to, from, offsetof(loop_state, store_at));
    memcpy(to->store_at, from->store_at, from->n_stores * sizeof from->store_at[0]);
    memcpy(to->store, from->store, from->n_stores * sizeof from->store[0]);
    memcpy(to->chains, from->chains, from->n_chains * sizeof from->chains[0]);
}

static bool has_unknown(const loop_state *s)
{
    for (int i = 0; i < 32; i++)
        if (s->r[i].opq)
            return true;
    for (int i = 0; i < 8; i++)
        if (s->f[i].kind == FLAG_UNKNOWN)
            return true;
    for (int i = 0; i < s->n_stores; i++)
        if (s->store[i].opq)
            return true;
    return false;
}

/* E1 as the start of the later iterations: what depends on the counter becomes unknown */
static void forget_v(loop_state *s)
{
    for (int i = 0; i < 32 + LOOP_STORES; i++) {
        loop_val *b = i < 32 ? &s->r[i] : &s->store[i - 32];
        if (b->sym)
            *b = (loop_val){ .opq = 0xFF };
        b->opq |= b->fsym;
        b->fsym = 0;
    }
    for (int i = 0; i < 8; i++)
        if (s->f[i].kind == FLAG_CHAIN)
            s->f[i].kind = FLAG_UNKNOWN;
    s->n_chains = 0;
}

/* a byte's value at V (a known byte without a call) */
static inline uint8_t value_at(const loop_state *s, const loop_val *b, uint64_t v)
{
    return b->sym || b->fsym ? loop_byte_value(s, b, v) : b->val;
}

static bool matches(const avr_t *avr, const loop_state *s, uint64_t v)
{
    for (int i = 0; i < 32; i++)
        if (avr->data[i] != value_at(s, &s->r[i], v))
            return false;
    for (int i = 0; i < 8; i++)
        if (avr->sreg[i] != (s->f[i].kind == FLAG_KNOWN ? s->f[i].val : loop_flag_value(s, i, v)))
            return false;
    for (int i = 0; i < s->n_stores; i++)
        if (avr->data[s->store_at[i]] != value_at(s, &s->store[i], v))
            return false;
    return (avr->data[R_SPL] | avr->data[R_SPH] << 8) == s->sp;
}

static void become(avr_t *avr, const loop_state *s, uint64_t v)
{
    for (int i = 0; i < 32; i++)
        avr->data[i] = value_at(s, &s->r[i], v);
    for (int i = 0; i < 8; i++)
        avr->sreg[i] = s->f[i].kind == FLAG_KNOWN ? s->f[i].val : loop_flag_value(s, i, v);
    for (int i = 0; i < s->n_stores; i++)
        avr->data[s->store_at[i]] = value_at(s, &s->store[i], v);
}

/* the first cycle at which something the loop reads may change */
static uint64_t window_end(const mcu_engine *e)
{
    uint64_t w = e->stop_at < e->next_event ? e->stop_at : e->next_event;
    const avr_cycle_timer_slot_t *t = e->avr->cycle_timers.timer;
    return t && t->when < w ? t->when : w;
}

/* a counted loop's end state after iteration j has the form k + s*(j+1) in each counter (star: k + s*j),
 * E1's known bytes elsewhere; a flag the iteration did not write is E1's (nothing read it: it was unknown) */
static bool counted_form(loop_state *end, const loop_state *star, const loop_state *e1, const int8_t *step)
{
    for (int i = 0; i < 8; i++)
        if (end->f[i].kind == FLAG_UNKNOWN)
            end->f[i] = e1->f[i];
    if (has_unknown(end) || end->sp != e1->sp || end->n_stores != e1->n_stores)
        return false;
    for (int i = 0; i < 32; i++) {
        const loop_val *b = &end->r[i];
        if (step[i] ? !b->sym || b->byte || b->sign != step[i] || (uint8_t)(b->k - star->r[i].k - (uint32_t)step[i])
                    : !loop_is_known(b) || b->val != e1->r[i].val)
            return false;
    }
    for (int i = 0; i < end->n_stores; i++)
        if (end->store_at[i] != e1->store_at[i] || !loop_is_known(&end->store[i]) ||
            end->store[i].val != e1->store[i].val)
            return false;
    return true;
}

/* iterations 1..m proved from E1's form (x->s on entry: E1 with the counter's bytes unknown; a counted
 * loop's: its counters k + s*j, the flags unknown) */
static bool prove(loop_run *x, const loop_state *star, const loop_state *e1, const int8_t *step, uint64_t m)
{
    copy_state(&x->s, star);
    x->j_first = 1;
    x->j_last = m;
    x->counted = step != NULL;
    if (!loop_eval(x))
        return false;
    return step ? counted_form(&x->s, star, e1, step) : !has_unknown(&x->s) && loop_same(&x->s, e1);
}

/* a loop that read no timer counter and changed known registers: those that changed by the same step in
 * iterations 0 and 1 are its counters (those that changed only in iteration 0 were set, not counted);
 * false when there are none, or a register changed otherwise */
static bool find_counters(loop_run *x, const loop_state *s0, const loop_state *e1, int8_t step[32])
{
    bool changed = false;
    for (int i = 0; i < 32; i++)
        changed |= loop_is_known(&s0->r[i]) && loop_is_known(&e1->r[i]) && s0->r[i].val != e1->r[i].val;
    if (!changed)
        return false;
    copy_state(&x->s, e1);
    x->j_first = x->j_last = 1;
    x->counted = false;
    if (!loop_eval(x) || x->read_v)
        return false;
    bool any = false;
    for (int i = 0; i < 32; i++) {
        const loop_val *a = &s0->r[i], *b = &e1->r[i], *c = &x->s.r[i];
        step[i] = 0;
        if (!loop_is_known(a) || !loop_is_known(b) || !loop_is_known(c) || a->val == b->val)
            continue;
        int8_t d1 = (int8_t)(b->val - a->val), d2 = (int8_t)(c->val - b->val);
        if (d2 && d2 != d1)
            return false;
        step[i] = d2;
        any |= d2 != 0;
    }
    return any;
}

/* the counters a counted loop had last time stepped as before in iteration 0 (any choice of counters
 * whose steps iteration 0 took is sound: the proof checks the rest; this one saves iteration 1's run) */
static bool same_counters(const int8_t step[32], const loop_state *s0, const loop_state *e1)
{
    for (int i = 0; i < 32; i++)
        if (step[i] && (!loop_is_known(&s0->r[i]) || !loop_is_known(&e1->r[i]) ||
                        (int8_t)(e1->r[i].val - s0->r[i].val) != step[i]))
            return false;
    return true;
}

/* E1's form with each counter k + s*j (k its value before iteration 0) and the flags unknown */
static void count_from(loop_state *star, const loop_state *s0, const int8_t step[32])
{
    for (int i = 0; i < 32; i++)
        if (step[i])
            star->r[i] = (loop_val){ .sym = true, .sign = step[i], .k = s0->r[i].val };
    for (int i = 0; i < 8; i++)
        star->f[i] = (loop_flag){ FLAG_UNKNOWN, 0, 0 };
    star->n_chains = 0;
}

/* not provable now: recorded again later (the path may have been another one's, or the loop was not
 * waiting yet), after twice as long for each failure in a row (a loop that computes, not one that
 * waits, is soon tried rarely enough to cost nothing) */
static void refuse(mcu_poll *p, loop_head *lp, uint64_t now)
{
    p->refused++;
    lp->have = false;
    if (lp->fails < BACK_OFF - 4)
        lp->fails++;
    /* (a loop whose iteration outgrew the trace never got a period: it is at least LOOP_TRACE cycles) */
    lp->retry_at = now + ((uint64_t)(lp->t.period ? lp->t.period : LOOP_TRACE) << (4 + lp->fails));
}

static void try_arm(mcu_engine *e, mcu_poll *p, loop_head *lp)
{
    avr_t *avr = e->avr;
    uint64_t c = avr->cycle, period = lp->t.period, w = window_end(e);
    if (avr->state != cpu_Running || avr_has_pending_interrupts(avr) || !period || w <= c + 1)
        return;
    uint64_t room = (w - 1 - c) / period; /* whole iterations that end before w */
    if (room < MIN_SKIP + 1)
        return;
    loop_run x = { .avr = avr, .io = &p->io, .t = &lp->t, .start = c };
    state_from_avr(&x.s, avr);
    loop_state s0, e1, star;
    copy_state(&s0, &x.s);
    if (!loop_eval(&x)) {
        refuse(p, lp, c);
        return;
    }
    copy_state(&e1, &x.s);
    copy_state(&star, &x.s);
    uint64_t v0 = x.v_lo;
    int8_t counters[32];
    const int8_t *step = NULL;
    forget_v(&star);
    if (!x.read_v && lp->counted && same_counters(lp->step, &s0, &e1))
        step = lp->step;
    else if (!x.read_v && find_counters(&x, &s0, &e1, counters))
        step = counters;
    lp->counted = false;
    if (step)
        count_from(&star, &s0, step);
    uint64_t m = room - 1;
    if (!prove(&x, &star, &e1, step, m)) { /* the largest m that proves (a smaller range proves if a larger does) */
        if (!prove(&x, &star, &e1, step, MIN_SKIP)) {
            if (x.range_limited)
                lp->retry_at = c + MIN_SKIP * period; /* (the loop ends within a few iterations) */
            else
                refuse(p, lp, c);
            return;
        }
        uint64_t good = MIN_SKIP, bad = m;
        while (bad - good > 1) {
            uint64_t mid = good + (bad - good) / 2;
            if (prove(&x, &star, &e1, step, mid))
                good = mid;
            else
                bad = mid;
        }
        m = good;
        prove(&x, &star, &e1, step, m);
    }
    if (step && step != lp->step)
        memcpy(lp->step, step, sizeof lp->step);
    lp->counted = step != NULL;
    lp->fails = 0;
    p->armed = lp;
    p->armed_start = c;
    p->armed_m = m;
    p->armed_n = 0;
    p->armed_istate = avr->interrupt_state;
    p->armed_resets = e->resets;
    copy_state(&p->e1, &e1);
    copy_state(&p->e2, &x.s);
    p->v0 = v0;
    p->vm = x.v_hi;
    e->poll_watch = true;
}

static void record(mcu_engine *e, mcu_poll *p, uint32_t pc_before)
{
    loop_head *lp = p->rec;
    loop_trace *t = &lp->t;
    avr_t *avr = e->avr;
    if (t->n >= LOOP_TRACE || avr->state != cpu_Running) {
        p->rec = NULL;
        e->poll_watch = false;
        refuse(p, lp, avr->cycle);
        return;
    }
    t->pc[t->n] = pc_before;
    t->end[t->n++] = avr->cycle;
    if (avr->pc != t->head)
        return;
    t->period = (uint32_t)(avr->cycle - p->rec_begin);
    lp->have = true;
    p->rec = NULL;
    e->poll_watch = false;
    try_arm(e, p, lp);
}

static void check_armed(mcu_engine *e, mcu_poll *p)
{
    loop_head *lp = p->armed;
    avr_t *avr = e->avr;
    p->armed_n++;
    if (avr->pc != lp->t.head && p->armed_n < lp->t.n)
        return;
    p->armed = NULL;
    e->poll_watch = false;
    uint64_t period = lp->t.period;
    if (avr->pc != lp->t.head || p->armed_n != lp->t.n || avr->cycle != p->armed_start + period ||
        avr->interrupt_state != p->armed_istate || e->resets != p->armed_resets)
        return; /* (something else happened: nothing was changed) */
    if (!matches(avr, &p->e1, p->v0)) {
        p->mismatches++;
        lp->dead = true;
        return;
    }
    become(avr, &p->e2, p->vm);
    avr->cycle += p->armed_m * period;
    e->instructions += p->armed_m * lp->t.n;
    p->skipped += p->armed_m * period;
    p->skips++;
}

/* the loop at pc; a new one takes the place of the one reached longest ago when all are taken */
static loop_head *head_at(mcu_poll *p, uint32_t pc, uint64_t now)
{
    loop_head *oldest = &p->loops[0];
    for (int i = 0; i < p->n_loops; i++) {
        if (p->loops[i].t.head == pc)
            return &p->loops[i];
        if (p->loops[i].seen < oldest->seen)
            oldest = &p->loops[i];
    }
    loop_head *lp = p->n_loops < LOOPS ? &p->loops[p->n_loops++] : oldest;
    if (lp == p->armed || lp == p->rec)
        return NULL;
    for (int i = 0; i < SEEN; i++) /* (the cache's pointers to what it was) */
        if (p->seen[i].head == lp)
            p->seen[i].head = NULL;
    memset(lp, 0, sizeof *lp);
    lp->t.head = pc;
    lp->seen = now;
    return lp;
}

/* after each instruction that jumped backward, and each while a loop is recorded or checked */
void mcu_poll_step(mcu_engine *e, uint32_t pc_before)
{
    mcu_poll *p = e->poll;
    avr_t *avr = e->avr;
    if (p->rec) {
        record(e, p, pc_before);
        return;
    }
    if (p->armed) {
        check_armed(e, p);
        return;
    }
    uint16_t w = (uint16_t)(avr->flash[pc_before] | avr->flash[pc_before + 1] << 8);
    /* a loop closes with RJMP, BRBS/BRBC (both 11110...), JMP, IJMP or EIJMP; not a return, a call or an
     * interrupt's entry */
    if ((w & 0xF000) != 0xC000 && (w & 0xF800) != 0xF000 && (w & 0xFE0E) != 0x940C && (w & 0xFFEF) != 0x9409)
        return;
    uint32_t h = (avr->pc >> 1) % SEEN;
    uint64_t now = avr->cycle;
    if (p->seen[h].pc != avr->pc || now - p->seen[h].cycle >= LOOP_CLOSE) {
        if (p->seen[h].pc != avr->pc) /* (the same pc keeps its entry: a search of the heads costs) */
            p->seen[h].head = NULL;
        p->seen[h].pc = avr->pc;
        p->seen[h].cycle = now;
        return;
    }
    p->seen[h].cycle = now;
    loop_head *lp = p->seen[h].head;
    if (!lp && !(lp = p->seen[h].head = head_at(p, avr->pc, now)))
        return;
    lp->seen = now;
    if (lp->dead || now < lp->retry_at)
        return;
    if (!lp->have) {
        lp->t.n = 0;
        p->rec = lp;
        p->rec_begin = now;
        e->poll_watch = true;
        return;
    }
    try_arm(e, p, lp);
}
