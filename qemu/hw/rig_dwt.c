/*
 * The Cortex-M4's data watchpoint and trace unit (DWT), ARMv7-M Architecture Reference Manual C1.8,
 * for its cycle counter: firmwares time code and busy-wait microseconds with DWT_CYCCNT, which QEMU's
 * ARMv7-M leaves reading 0 (a busy-wait then never ends). CYCCNT counts the "hclk" clock's cycles in
 * virtual time while DWT_CTRL.CYCCNTENA is set (under -icount, instructions times the icount period):
 * its count divided by the clock is the time the firmware ran, as the rig defines sim time. It follows
 * clock changes (a firmware switching from 16 to 168 MHz counts faster from the switch on) and wraps
 * at 2^32. DEMCR.TRCENA is not required (QEMU does not model DEMCR). The comparators, the profiling
 * counters (CPICNT ... FOLDCNT, read 0) and PC sampling are not modelled.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/qdev-clock.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"

#define DWT_CTRL 0x000
#define DWT_CYCCNT 0x004
#define CTRL_CYCCNTENA (1u << 0)
/* the Cortex-M4's DWT: four comparators, no trace packets or external triggers (reads of CTRL) */
#define CTRL_ID 0x40000000u
#define CTRL_WRITABLE 0x01FFFFFFu

static uint32_t dwt_cyccnt(RigDwtState *s)
{
    if (!(s->ctrl & CTRL_CYCCNTENA)) {
        return s->cyccnt_base;
    }
    int64_t ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL) - s->base_ns;
    return s->cyccnt_base + (uint32_t)clock_ns_to_ticks(s->hclk, ns);
}

/* The count so far becomes the base, counted on from now (at the current clock) */
static void dwt_restart(RigDwtState *s)
{
    s->cyccnt_base = dwt_cyccnt(s);
    s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
}

static void dwt_clock_changes(void *opaque, ClockEvent event)
{
    RigDwtState *s = opaque;
    if (event == ClockPreUpdate) {
        dwt_restart(s); /* the cycles at the old frequency */
    } else {
        s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    }
}

static uint64_t dwt_read(void *opaque, hwaddr offset, unsigned size)
{
    RigDwtState *s = opaque;
    switch (offset) {
    case DWT_CTRL:
        return CTRL_ID | s->ctrl;
    case DWT_CYCCNT:
        return dwt_cyccnt(s);
    default:
        return 0;
    }
}

static void dwt_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigDwtState *s = opaque;
    switch (offset) {
    case DWT_CTRL:
        dwt_restart(s);
        s->ctrl = (uint32_t)value & CTRL_WRITABLE;
        break;
    case DWT_CYCCNT:
        s->cyccnt_base = (uint32_t)value;
        s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
        break;
    default:
        qemu_log_mask(LOG_UNIMP, "rig-dwt: write of offset 0x%" HWADDR_PRIx " (not modelled)\n", offset);
    }
}

static const MemoryRegionOps dwt_ops = {
    .read = dwt_read,
    .write = dwt_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void dwt_reset(DeviceState *dev)
{
    RigDwtState *s = RIG_DWT(dev);
    s->ctrl = 0;
    s->cyccnt_base = 0;
    s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
}

static void dwt_init(Object *obj)
{
    RigDwtState *s = RIG_DWT(obj);
    memory_region_init_io(&s->iomem, obj, &dwt_ops, s, TYPE_RIG_DWT, 0x1000);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    s->hclk = qdev_init_clock_in(DEVICE(obj), "hclk", dwt_clock_changes, s, ClockPreUpdate | ClockUpdate);
}

static void dwt_class_init(ObjectClass *klass, void *data) { DEVICE_CLASS(klass)->reset = dwt_reset; }

static const TypeInfo dwt_info = {
    .name = TYPE_RIG_DWT,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigDwtState),
    .instance_init = dwt_init,
    .class_init = dwt_class_init,
};

static void dwt_register_types(void) { type_register_static(&dwt_info); }

type_init(dwt_register_types)
