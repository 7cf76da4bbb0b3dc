/* The timer modes simavr 1.6 lacks. Its tables for the ATmega2560 and ATmega328P have no phase correct
 * modes but those with TOP = OCRnA (16-bit timers: WGM 1-3 and 8-11; 8-bit: WGM 1 and 5): a timer set to
 * one (the reference FC's motor timers run WGM 10) gets simavr's "no mode", with TOP 0, and simavr then
 * runs an overflow every prescaler period: a cycle timer every 8 cycles per timer, most of the engine's
 * time, and overflow flags no chip would set. The glue stops such a timer in simavr after every write that
 * configures it (its mode and clock bits, its compare registers, its counter): TCNTn reads 0 and it sets
 * no flag, as a stopped timer. Its motor pulses are the glue's, from the registers (pwm.c), as before. */
#include <string.h>

#include <simavr/avr_timer.h>

#include "glue.h"

#include <stdlib.h>

typedef struct {
    avr_timer_t *timer;
    avr_io_write_t c;
    void *param;
} stopped_wrap;

#define WRAPS 64

struct mcu_timer_wraps {
    stopped_wrap w[WRAPS];
    int n;
    bool stock; /* simavr's own behaviour back (bench/mcu_rates.py measures what this saves) */
};

/* simavr's cycle timers of this timer cancelled (its overflow and its compare matches) */
static void stop_in_simavr(avr_t *avr, avr_timer_t *p)
{
    for (bool again = true; again;) {
        again = false;
        for (avr_cycle_timer_slot_t *t = avr->cycle_timers.timer; t; t = t->next) {
            bool mine = t->param == p;
            for (int i = 0; i < AVR_TIMER_COMP_COUNT; i++)
                mine = mine || t->param == &p->comp[i];
            if (mine) {
                avr_cycle_timer_cancel(avr, t->timer, t->param);
                again = true;
                break;
            }
        }
    }
    p->tov_cycles = 0;
}

static void wrapped(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    stopped_wrap *w = param;
    const struct mcu_timer_wraps *all = ((mcu_engine *)avr->custom.data)->timer_wraps;
    if (w->c)
        w->c(avr, addr, v, w->param);
    else
        avr->data[addr] = v;
    if (w->timer->mode.kind == avr_timer_wgm_none && !all->stock)
        stop_in_simavr(avr, w->timer);
}

static void wrap(mcu_engine *e, avr_timer_t *p, avr_io_addr_t addr)
{
    struct mcu_timer_wraps *t = e->timer_wraps;
    if (!addr || t->n == WRAPS)
        return;
    avr_io_addr_t io = AVR_DATA_TO_IO(addr);
    for (int i = 0; i < t->n; i++)
        if (e->avr->io[io].w.param == &t->w[i])
            return;
    stopped_wrap *w = &t->w[t->n++];
    *w = (stopped_wrap){ p, e->avr->io[io].w.c, e->avr->io[io].w.param };
    e->avr->io[io].w.c = wrapped;
    e->avr->io[io].w.param = w;
}

void mcu_timer_modes_stock(mcu_engine *e, bool stock)
{
    if (e->timer_wraps)
        e->timer_wraps->stock = stock;
}

void mcu_timer_modes_attach(mcu_engine *e)
{
    e->timer_wraps = calloc(1, sizeof *e->timer_wraps);
    if (!e->timer_wraps)
        return;
    for (avr_io_t *port = e->avr->io_port; port; port = port->next) {
        if (strcmp(port->kind, "timer"))
            continue;
        avr_timer_t *p = (avr_timer_t *)port;
        for (int i = 0; i < 4; i++) {
            wrap(e, p, p->wgm[i].reg);
            wrap(e, p, p->cs[i].reg);
        }
        for (int i = 0; i < AVR_TIMER_COMP_COUNT; i++) {
            wrap(e, p, p->comp[i].r_ocr);
            wrap(e, p, p->comp[i].r_ocrh);
        }
        wrap(e, p, p->r_tcnt);
        wrap(e, p, p->r_tcnth);
    }
}
