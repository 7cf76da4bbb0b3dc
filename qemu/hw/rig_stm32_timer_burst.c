/*
 * The timers' DMA bursts (RM0090 17.3.19, "DMA burst mode", and DCR/DMAR, 17.4.20-17.4.21): a DMA stream
 * writing (or reading) TIMx_DMAR reaches the register DCR.DBA names, then the next ones, DBL + 1 of them;
 * after each but the last the timer raises the request that started the burst again, so one update event
 * writes CCR1..CCR4 (Betaflight's DShot by "DMA burst"). The index restarts when the burst is done; DCR
 * is written by software between bursts.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "rig_stm32_timer_regs.h"

#define DCR_DBA 0x1Fu
#define DCR_DBL_SHIFT 8

uint32_t rig_stm32_timer_dmar(RigStm32TimerState *s, bool write, uint32_t value)
{
    unsigned dba = s->regs[DCR] & DCR_DBA, dbl = s->regs[DCR] >> DCR_DBL_SHIFT & 0x1F;
    hwaddr target = 4 * (hwaddr)(dba + s->burst);
    uint32_t read = 0;
    if (++s->burst > dbl) {
        s->burst = 0;
    } else {
        s->dma_pending |= s->dma_sent; /* the next transfer of the burst (sent by settle) */
    }
    if (target == registers[DMAR].offset) { /* (a burst onto DMAR itself reaches nothing) */
        return 0;
    }
    /* through the timer's own register access, as a write or read by the core would go */
    if (write) {
        s->iomem.ops->write(s, target, value, 4);
    } else {
        read = (uint32_t)s->iomem.ops->read(s, target, 4);
    }
    return read;
}
