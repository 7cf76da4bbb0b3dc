/* The abstract run of one polling-loop iteration (polling.h): the AVR instructions such loops use, their
 * flags as Atmel's "AVR Instruction Set Manual" defines them, on known bytes and on bytes of s*V + k
 * (loop_values.c). Anything else (a store to an I/O register, an instruction not below, an unknown value
 * used) ends the run: the loop is then simply run. */
#include <string.h>

#include "polling.h"

/* SUB, SBC, SUBI, SBCI, CP, CPC, CPI: known, or a subtraction chain on V (bytes from 0 up) */
static bool subtract(loop_run *x, int d, loop_val a, loop_val b, bool with_carry, bool keep)
{
    loop_state *s = &x->s;
    loop_flag *cf = &s->f[S_C];
    if (loop_is_known(&a) && loop_is_known(&b) && (!with_carry || cf->kind == FLAG_KNOWN)) {
        uint8_t cin = with_carry ? cf->val : 0, r = (uint8_t)(a.val - b.val - cin);
        uint8_t borrow = (uint8_t)((~a.val & b.val) | (b.val & r) | (r & ~a.val));
        bool v = ((a.val & ~b.val & ~r) | (~a.val & b.val & r)) >> 7 & 1;
        loop_flag z = s->f[S_Z];
        loop_nzs(x, r, v);
        if (with_carry && r == 0)
            s->f[S_Z] = z; /* (Z stays as it was on a zero byte) */
        loop_set_flag(x, S_H, borrow >> 3 & 1);
        loop_set_flag(x, S_C, borrow >> 7 & 1);
        if (keep)
            s->r[d] = loop_known(r);
        return true;
    }
    if (s->n_chains >= LOOP_CHAINS)
        return loop_fail(x, "too many subtractions");
    loop_chain c;
    if (!with_carry) {
        loop_val *v = a.sym ? &a : &b, *o = a.sym ? &b : &a;
        if (!v->sym || v->byte != 0 || !loop_is_known(o))
            return loop_fail(x, "a subtraction on unknown bytes");
        c = (loop_chain){ v->sign, 1, a.sym, v->k, o->val };
    } else {
        if (cf->kind != FLAG_CHAIN || s->f[S_Z].kind != FLAG_CHAIN || s->f[S_Z].chain != cf->chain)
            return loop_fail(x, "a subtraction with an unknown carry");
        c = s->chains[cf->chain];
        loop_val *v = c.v_is_rd ? &a : &b, *o = c.v_is_rd ? &b : &a;
        unsigned n = 8u * c.m;
        uint32_t low_mask = (uint32_t)((1ull << n) - 1);
        if (c.m >= 4 || !loop_is_known(o))
            return loop_fail(x, "a subtraction on unknown bytes");
        if (v->sym) {
            if (v->byte != c.m || v->sign != c.sign || ((v->k - c.k) & low_mask))
                return loop_fail(x, "a subtraction across two values");
            c.k = v->k;
        } else if (loop_is_known(v)) { /* a known byte above V's: V's low bytes must not carry into it */
            int64_t low = (int64_t)(c.k & low_mask);
            int64_t ends[2] = { low + c.sign * (int64_t)x->v_lo, low + c.sign * (int64_t)x->v_hi };
            for (int i = 0; i < 2; i++)
                if (ends[i] < 0 || ends[i] >= (int64_t)(1ll << n))
                    return loop_out_of_range(x, "a known byte the timer counter carries into");
            c.k = (c.k & low_mask) | (uint32_t)v->val << n;
        } else
            return loop_fail(x, "a subtraction on unknown bytes");
        c.c = (c.c & low_mask) | (uint32_t)o->val << n;
        c.m++;
    }
    uint8_t idx = s->n_chains++;
    s->chains[idx] = c;
    static const int chained[] = { S_C, S_Z, S_N, S_V, S_S, S_H };
    for (int i = 0; i < 6; i++)
        s->f[chained[i]] = (loop_flag){ FLAG_CHAIN, 0, idx };
    if (keep) {
        uint32_t cmask = (uint32_t)((1ull << (8u * c.m)) - 1);
        s->r[d] = (loop_val){ .sym = true,
                              .byte = (uint8_t)(c.m - 1),
                              .sign = c.v_is_rd ? c.sign : (int8_t)-c.sign,
                              .k = c.v_is_rd ? c.k - (c.c & cmask) : (c.c & cmask) - c.k };
    }
    return true;
}

/* ADD, ADC and the logic operations on known bytes (and the few moves they make of V's bytes) */
static bool logic(loop_run *x, int op, int d, loop_val a, loop_val b)
{
    if (!loop_is_known(&a) || !loop_is_known(&b)) {
        bool a0 = loop_is_known(&a) && a.val == 0, b0 = loop_is_known(&b) && b.val == 0;
        if (op == 2 && (a0 || b0)) { /* OR with 0: a move */
            x->s.r[d] = a0 ? b : a;
            loop_set_flag(x, S_V, 0);
            loop_unknown_flag(x, S_N);
            loop_unknown_flag(x, S_Z);
            loop_unknown_flag(x, S_S);
            return true;
        }
        return loop_fail(x, "arithmetic on unknown bytes");
    }
    uint8_t r;
    switch (op) {
    case 0:
        r = a.val & b.val;
        break;
    case 1:
        r = a.val ^ b.val;
        break;
    default:
        r = a.val | b.val;
        break;
    }
    loop_nzs(x, r, 0);
    x->s.r[d] = loop_known(r);
    return true;
}

static bool add(loop_run *x, int d, loop_val a, loop_val b, bool with_carry)
{
    loop_flag *cf = &x->s.f[S_C];
    if (!loop_is_known(&a) || !loop_is_known(&b) || (with_carry && cf->kind != FLAG_KNOWN))
        return loop_fail(x, "an addition on unknown bytes");
    uint8_t r = (uint8_t)(a.val + b.val + (with_carry ? cf->val : 0));
    uint8_t carry = (uint8_t)((a.val & b.val) | (b.val & ~r) | (~r & a.val));
    loop_nzs(x, r, ((a.val & b.val & ~r) | (~a.val & ~b.val & r)) >> 7 & 1);
    loop_set_flag(x, S_H, carry >> 3 & 1);
    loop_set_flag(x, S_C, carry >> 7 & 1);
    x->s.r[d] = loop_known(r);
    return true;
}

static bool word_add(loop_run *x, int d, int k, bool sub)
{
    loop_val *lo = &x->s.r[d], *hi = &x->s.r[d + 1];
    if (!loop_is_known(lo) || !loop_is_known(hi))
        return loop_fail(x, "ADIW/SBIW on unknown bytes");
    uint16_t a = (uint16_t)(lo->val | hi->val << 8), r = (uint16_t)(sub ? a - k : a + k);
    bool a15 = a >> 15, r15 = r >> 15;
    loop_set_flag(x, S_N, r15);
    loop_set_flag(x, S_Z, r == 0);
    loop_set_flag(x, S_V, sub ? a15 && !r15 : !a15 && r15);
    loop_set_flag(x, S_S, r15 ^ (sub ? a15 && !r15 : !a15 && r15));
    loop_set_flag(x, S_C, sub ? r15 && !a15 : !r15 && a15);
    *lo = loop_known((uint8_t)r);
    *hi = loop_known((uint8_t)(r >> 8));
    return true;
}

static bool one_operand(loop_run *x, int op, int d)
{
    loop_val *v = &x->s.r[d];
    if (v->sym && (op == 0xA || op == 0x3)) { /* DEC, INC of a counter: SUBI 1, SUBI 0xFF with C and H kept */
        loop_flag carry = x->s.f[S_C], half = x->s.f[S_H];
        if (!subtract(x, d, *v, loop_known(op == 0xA ? 1 : 0xFF), false, true))
            return false;
        x->s.f[S_C] = carry;
        x->s.f[S_H] = half;
        return true;
    }
    if (!loop_is_known(v))
        return loop_fail(x, "an operation on an unknown byte");
    uint8_t a = v->val, r;
    bool c;
    switch (op) {
    case 0x0: /* COM */
        r = (uint8_t)~a;
        loop_nzs(x, r, 0);
        loop_set_flag(x, S_C, 1);
        break;
    case 0x2: /* SWAP */
        r = (uint8_t)(a << 4 | a >> 4);
        break;
    case 0x3: /* INC */
        r = (uint8_t)(a + 1);
        loop_nzs(x, r, r == 0x80);
        break;
    case 0xA: /* DEC */
        r = (uint8_t)(a - 1);
        loop_nzs(x, r, r == 0x7F);
        break;
    case 0x5: /* ASR */
    case 0x6: /* LSR */
    case 0x7: /* ROR */
        if (op == 0x7 && x->s.f[S_C].kind != FLAG_KNOWN)
            return loop_fail(x, "ROR of an unknown carry");
        c = a & 1;
        r = (uint8_t)(a >> 1 | (op == 0x5 ? a & 0x80 : op == 0x7 ? x->s.f[S_C].val << 7 : 0));
        loop_nzs(x, r, (r >> 7) ^ c);
        loop_set_flag(x, S_C, c);
        break;
    default:
        return loop_fail(x, "an instruction polling loops do not use");
    }
    *v = loop_known(r);
    return true;
}

static uint32_t words(uint16_t w) /* 2 for LDS, STS, JMP, CALL */
{
    return (w & 0xFC0F) == 0x9000 || (w & 0xFE0C) == 0x940C ? 2 : 1;
}

/* one instruction at pc; *next: where the run goes on */
static bool step(loop_run *x, uint32_t pc, uint32_t offset, uint32_t *next)
{
    avr_t *avr = x->avr;
    loop_state *s = &x->s;
    uint16_t w = (uint16_t)(avr->flash[pc] | avr->flash[pc + 1] << 8);
    uint16_t w2 = (uint16_t)(avr->flash[pc + 2] | avr->flash[pc + 3] << 8);
    int d = w >> 4 & 0x1F, r = (w >> 5 & 0x10) | (w & 0x0F), dh = 16 + (w >> 4 & 0xF);
    uint8_t imm = (uint8_t)((w >> 4 & 0xF0) | (w & 0x0F));
    loop_val v;
    bool bit;
    *next = pc + 2;
    switch (w >> 12) {
    case 0x0:
        if (w == 0)
            return true;
        if ((w & 0xFF00) == 0x0100) { /* MOVW */
            s->r[2 * (w >> 4 & 0xF)] = s->r[2 * (w & 0xF)];
            s->r[2 * (w >> 4 & 0xF) + 1] = s->r[2 * (w & 0xF) + 1];
            return true;
        }
        switch (w >> 10 & 3) {
        case 1:
            return subtract(x, d, s->r[d], s->r[r], true, false); /* CPC */
        case 2:
            return subtract(x, d, s->r[d], s->r[r], true, true); /* SBC */
        case 3:
            return add(x, d, s->r[d], s->r[r], false);
        }
        return loop_fail(x, "an instruction polling loops do not use");
    case 0x1:
        switch (w >> 10 & 3) {
        case 0: /* CPSE */
            if (!loop_is_known(&s->r[d]) || !loop_is_known(&s->r[r]))
                return loop_fail(x, "CPSE on unknown bytes");
            if (s->r[d].val == s->r[r].val)
                *next += 2 * words(w2);
            return true;
        case 1:
            return subtract(x, d, s->r[d], s->r[r], false, false); /* CP */
        case 2:
            return subtract(x, d, s->r[d], s->r[r], false, true); /* SUB */
        default:
            return add(x, d, s->r[d], s->r[r], true); /* ADC */
        }
    case 0x2:
        if ((w >> 10 & 3) == 3) { /* MOV */
            s->r[d] = s->r[r];
            return true;
        }
        if ((w >> 10 & 3) == 1 && d == r) { /* EOR r, r: 0 whatever r was */
            s->r[d] = loop_known(0);
            loop_nzs(x, 0, 0);
            return true;
        }
        return logic(x, w >> 10 & 3, d, s->r[d], s->r[r]);
    case 0x3:
        return subtract(x, dh, s->r[dh], loop_known(imm), false, false); /* CPI */
    case 0x4:
        return subtract(x, dh, s->r[dh], loop_known(imm), true, true); /* SBCI */
    case 0x5:
        return subtract(x, dh, s->r[dh], loop_known(imm), false, true); /* SUBI */
    case 0x6:
        return logic(x, 2, dh, s->r[dh], loop_known(imm)); /* ORI */
    case 0x7:
        return logic(x, 0, dh, s->r[dh], loop_known(imm)); /* ANDI */
    case 0x8:
    case 0xA: { /* LDD / STD Y+q, Z+q */
        int q = (w >> 8 & 0x20) | (w >> 7 & 0x18) | (w & 7), base = w & 8 ? 28 : 30;
        if (!loop_is_known(&s->r[base]) || !loop_is_known(&s->r[base + 1]))
            return loop_fail(x, "an unknown pointer");
        uint16_t addr = (uint16_t)((s->r[base].val | s->r[base + 1].val << 8) + q);
        if (w & 0x0200)
            return loop_store(x, addr, s->r[d]);
        return loop_load(x, addr, offset, &v) && (s->r[d] = v, true);
    }
    case 0x9:
        break;
    case 0xB: { /* IN / OUT */
        uint16_t a = (uint16_t)(0x20 + ((w >> 5 & 0x30) | (w & 0xF)));
        if (w & 0x0800)
            return loop_store(x, a, s->r[d]);
        return loop_load(x, a, offset, &v) && (s->r[d] = v, true);
    }
    case 0xC:
    case 0xD: { /* RJMP / RCALL */
        int k = ((w & 0xFFF) ^ 0x800) - 0x800;
        if (w >> 12 == 0xD) {
            uint32_t ret = (pc + 2) >> 1;
            for (int i = 0; i < avr->address_size; i++, ret >>= 8)
                if (!loop_push(x, loop_known((uint8_t)ret)))
                    return false;
        }
        *next = (uint32_t)((int32_t)pc + 2 + 2 * k);
        return true;
    }
    case 0xE:
        s->r[dh] = loop_known(imm); /* LDI */
        return true;
    default: { /* 0xF: BRBS/BRBC, BLD/BST, SBRC/SBRS */
        int b = w & 7;
        if ((w & 0x0800) == 0) {
            if (!loop_flag_get(x, b, &bit))
                return false;
            if (bit == !(w & 0x0400)) /* BRBS taken on 1, BRBC on 0 */
                *next = (uint32_t)((int32_t)pc + 2 + 2 * ((((w >> 3) & 0x7F) ^ 0x40) - 0x40));
            return true;
        }
        if ((w & 0x0C08) == 0x0C00) { /* SBRC / SBRS */
            if (!loop_bit_get(x, &s->r[d], b, &bit))
                return false;
            if (bit == ((w & 0x0200) != 0))
                *next += 2 * words(w2);
            return true;
        }
        return loop_fail(x, "BLD/BST");
    }
    }
    /* 0x9xxx */
    if ((w & 0xFC0F) == 0x9000) { /* LDS / STS */
        *next = pc + 4;
        if (w & 0x0200)
            return loop_store(x, w2, s->r[d]);
        return loop_load(x, w2, offset, &v) && (s->r[d] = v, true);
    }
    if ((w & 0xFC00) == 0x9000) { /* LD/ST X, Y, Z with +/-, PUSH, POP */
        int mode = w & 0xF;
        bool st = w & 0x0200;
        if (mode == 0xF) {
            if (st)
                return loop_push(x, s->r[d]);
            return loop_pop(x, &v) && (s->r[d] = v, true);
        }
        int base = mode >= 0xC ? 26 : mode >= 0x9 ? 28 : mode >= 1 && mode <= 2 ? 30 : -1;
        int kind = mode >= 0xC ? mode - 0xC : mode >= 0x9 ? mode - 0x8 : mode; /* 0 plain, 1 post-inc, 2 pre-dec */
        if (base < 0 || kind > 2 || (kind && (d == base || d == base + 1)))
            return loop_fail(x, "an instruction polling loops do not use");
        if (!loop_is_known(&s->r[base]) || !loop_is_known(&s->r[base + 1]))
            return loop_fail(x, "an unknown pointer");
        uint16_t p = (uint16_t)(s->r[base].val | s->r[base + 1].val << 8);
        if (kind == 2)
            p--;
        bool ok = st ? loop_store(x, p, s->r[d]) : (loop_load(x, p, offset, &v) && (s->r[d] = v, true));
        if (kind == 1)
            p++;
        s->r[base] = loop_known((uint8_t)p);
        s->r[base + 1] = loop_known((uint8_t)(p >> 8));
        return ok;
    }
    if ((w & 0xFE0E) == 0x940C || (w & 0xFE0E) == 0x940E) { /* JMP / CALL */
        uint32_t k = (uint32_t)(((w >> 3 & 0x3E) | (w & 1)) << 16 | w2);
        if (w & 2) {
            uint32_t ret = (pc + 4) >> 1;
            for (int i = 0; i < avr->address_size; i++, ret >>= 8)
                if (!loop_push(x, loop_known((uint8_t)ret)))
                    return false;
        }
        *next = 2 * k;
        return true;
    }
    if (w == 0x9508) { /* RET */
        uint32_t to = 0;
        for (int i = 0; i < avr->address_size; i++) {
            if (!loop_pop(x, &v) || !loop_is_known(&v))
                return loop_fail(x, "a return to an unknown address");
            to = to << 8 | v.val;
        }
        *next = 2 * to;
        return true;
    }
    if ((w & 0xFF0F) == 0x9408) { /* BSET / BCLR: SEI, CLI, SEC, ... */
        loop_set_flag(x, w >> 4 & 7, !(w & 0x80));
        return true;
    }
    if ((w & 0xFE00) == 0x9400 && ((w & 0xF) <= 7 || (w & 0xF) == 0xA)) /* COM ... DEC */
        return one_operand(x, w & 0xF, d);
    if ((w & 0xFE00) == 0x9600) /* ADIW / SBIW */
        return word_add(x, 24 + 2 * (w >> 4 & 3), (w >> 2 & 0x30) | (w & 0xF), w & 0x100);
    if ((w & 0xFD00) == 0x9900) { /* SBIC / SBIS */
        if (!loop_load(x, (uint16_t)(0x20 + (w >> 3 & 0x1F)), offset, &v) || !loop_bit_get(x, &v, w & 7, &bit))
            return false;
        if (bit == ((w & 0x0200) != 0))
            *next += 2 * words(w2);
        return true;
    }
    return loop_fail(x, "an instruction polling loops do not use");
}

/* runs the iteration along the trace; false (x->why) when it cannot be proved */
bool loop_eval(loop_run *x)
{
    const loop_trace *t = x->t;
    uint32_t pc = t->head;
    uint64_t begin = t->end[t->n - 1] - t->period;
    x->read_v = x->range_limited = false;
    x->v_lo = x->counted ? x->j_first : 0;
    x->v_hi = x->counted ? x->j_last : 0;
    for (uint16_t i = 0; i < t->n; i++) {
        if (pc != t->pc[i])
            return loop_fail(x, "another path than the one run");
        uint32_t offset = (uint32_t)((i ? t->end[i - 1] : begin) - begin), next;
        x->fail_pc = pc;
        if (!step(x, pc, offset, &next))
            return false;
        pc = next;
    }
    return pc == t->head || loop_fail(x, "another path than the one run");
}
