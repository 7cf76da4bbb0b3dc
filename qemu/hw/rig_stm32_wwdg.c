/*
 * The STM32F405's window watchdog (WWDG), RM0090 section 20: CR (the 7-bit down-counter T[6:0] and WDGA,
 * which only a reset clears), CFR (the window W[6:0], the prescaler WDGTB, EWI, which only a reset
 * clears), SR's EWIF (cleared by writing 0). The counter counts down, whether WDGA is set or not, once
 * every 4096 * 2^WDGTB PCLK1 cycles in virtual time (20.3: t_WWDG = t_PCLK1 * 4096 * 2^WDGTB *
 * (T[5:0] + 1)); reaching 0x40 it sets EWIF, with EWI the WWDG interrupt (NVIC 0). With WDGA set, a reset
 * of the system (RCC_CSR.WWDGRSTF) when the counter passes from 0x40 to 0x3F, when CR is written while the
 * counter is above the window (W), or when CR is written with T6 clear. The registers answer only with
 * RCC_APB1ENR.WWDGEN; APB1RSTR.WWDGRST resets it. The counter starts at the first access with the clock
 * on (the chip's counts from the clock's enable, which the model does not see). PCLK1 is taken then and
 * when CR or CFR is written: a clock change while the watchdog counts is not followed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"

/* RM0090 table 109 (WWDG register map) */
enum { CR, CFR, SR };
static const RigRegister wwdg_registers[] = {
    [CR] = { 0x00, "CR", 0x0000007F, 0x000000FF },   /* T[6:0], WDGA */
    [CFR] = { 0x04, "CFR", 0x0000007F, 0x000003FF }, /* W[6:0], WDGTB, EWI */
    [SR] = { 0x08, "SR", 0x00000000, 0x00000001 },   /* EWIF: rc_w0 */
};
#define CR_T 0x7Fu
#define CR_T6 0x40u
#define CR_WDGA (1u << 7)
#define CFR_W 0x7Fu
#define CFR_WDGTB_SHIFT 7
#define CFR_EWI (1u << 9)
#define SR_EWIF (1u << 0)
#define EARLY_WAKEUP 0x40u
#define RCC_APB1ENR 0x40
#define APB1_WWDG 11
#define RCC_CSR_WWDGRSTF (1u << 30)

/* PCLK1 cycles a count */
static uint64_t count_cycles(RigStm32WwdgState *s) { return 4096ull << (s->cfr >> CFR_WDGTB_SHIFT & 0x3); }

/* The counts since base_ns (a count's ns need not be whole: 4096 * 8 cycles of 16 MHz are 2048 us, of
 * 42 MHz 780190.47 ns) */
static uint64_t counts(RigStm32WwdgState *s)
{
    if (s->hz == 0) { /* the first access with its clock on after a reset: counting from here */
        s->hz = rig_stm32_rcc_pclk_hz(s->rcc, 1);
        s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    }
    unsigned __int128 elapsed = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL) - s->base_ns;
    return elapsed * s->hz / ((unsigned __int128)NANOSECONDS_PER_SECOND * count_cycles(s));
}

static uint8_t counter(RigStm32WwdgState *s) { return (s->base_count - counts(s)) & CR_T; }

/* The next count that makes the counter 0x40 (EWIF) or, with WDGA, 0x3F (a reset), armed */
static void wwdg_arm(RigStm32WwdgState *s)
{
    uint64_t now = counts(s), next = UINT64_MAX;
    uint8_t value = counter(s);
    for (unsigned v = EARLY_WAKEUP - ((s->cr & CR_WDGA) ? 1 : 0); v <= EARLY_WAKEUP; v++) {
        uint64_t ahead = (value - v) & CR_T;
        next = MIN(next, now + (ahead ? ahead : CR_T + 1));
    }
    /* the first ns at which the count is reached */
    unsigned __int128 cycles_ns = (unsigned __int128)next * count_cycles(s) * NANOSECONDS_PER_SECOND;
    timer_mod(s->timer, s->base_ns + (int64_t)((cycles_ns + s->hz - 1) / s->hz));
}

/* The counter from now on counts down from @value at the current PCLK1 */
static void wwdg_rebase(RigStm32WwdgState *s, uint8_t value)
{
    s->base_count = value & CR_T;
    s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    s->hz = rig_stm32_rcc_pclk_hz(s->rcc, 1);
    wwdg_arm(s);
}

static void wwdg_irq_update(RigStm32WwdgState *s) { qemu_set_irq(s->irq, (s->sr & SR_EWIF) && (s->cfr & CFR_EWI)); }

static void wwdg_reset_system(RigStm32WwdgState *s)
{
    timer_del(s->timer);
    rig_stm32_rcc_watchdog_reset(s->rcc, RCC_CSR_WWDGRSTF, RIG_RESET_WWDG);
}

static void wwdg_event(void *opaque)
{
    RigStm32WwdgState *s = opaque;
    uint8_t value = counter(s);
    if (value == EARLY_WAKEUP) {
        s->sr |= SR_EWIF;
        wwdg_irq_update(s);
    } else if (value == EARLY_WAKEUP - 1 && (s->cr & CR_WDGA)) {
        wwdg_reset_system(s);
        return;
    }
    wwdg_arm(s);
}

static bool wwdg_clocked(RigStm32WwdgState *s) { return rig_stm32_rcc_enabled(s->rcc, RCC_APB1ENR, APB1_WWDG); }

static uint64_t wwdg_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32WwdgState *s = opaque;
    int i = rig_register_index(wwdg_registers, ARRAY_SIZE(wwdg_registers), offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-wwdg: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    if (!wwdg_clocked(s)) {
        return 0;
    }
    return i == CR ? (s->cr & CR_WDGA) | counter(s) : i == CFR ? s->cfr : s->sr;
}

static void wwdg_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32WwdgState *s = opaque;
    uint32_t v = value;
    int i = rig_register_index(wwdg_registers, ARRAY_SIZE(wwdg_registers), offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-wwdg: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    if (!wwdg_clocked(s)) {
        return;
    }
    switch (i) {
    case CR: {
        bool was_active = s->cr & CR_WDGA;
        if (was_active && counter(s) > (s->cfr & CFR_W)) {
            wwdg_reset_system(s); /* refreshed before the window opened (20.3) */
            return;
        }
        s->cr |= v & CR_WDGA; /* WDGA: set by software, cleared by a reset */
        if ((s->cr & CR_WDGA) && !(v & CR_T6)) {
            wwdg_reset_system(s); /* T6 cleared: an immediate reset */
            return;
        }
        wwdg_rebase(s, v & CR_T);
        break;
    }
    case CFR:
        wwdg_rebase(s, counter(s)); /* (before WDGTB changes the count's length) */
        s->cfr = (v & (CFR_W | 0x3u << CFR_WDGTB_SHIFT)) | ((s->cfr | v) & CFR_EWI); /* EWI: as WDGA */
        wwdg_rebase(s, counter(s));
        wwdg_irq_update(s);
        break;
    default: /* SR */
        s->sr &= v;
        wwdg_irq_update(s);
    }
}

static const MemoryRegionOps wwdg_ops = {
    .read = wwdg_read,
    .write = wwdg_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void wwdg_reset(DeviceState *dev)
{
    RigStm32WwdgState *s = RIG_STM32_WWDG(dev);
    s->cr = wwdg_registers[CR].reset & CR_WDGA;
    s->cfr = wwdg_registers[CFR].reset;
    s->sr = wwdg_registers[SR].reset;
    s->base_count = wwdg_registers[CR].reset & CR_T;
    s->base_ns = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    s->hz = 0; /* (counting from the first access: and the RCC may not be reset yet) */
    timer_del(s->timer);
    qemu_set_irq(s->irq, 0);
}

static void wwdg_init(Object *obj)
{
    RigStm32WwdgState *s = RIG_STM32_WWDG(obj);
    memory_region_init_io(&s->iomem, obj, &wwdg_ops, s, TYPE_RIG_STM32_WWDG, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq);
    s->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, wwdg_event, s);
}

static Property wwdg_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32WwdgState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void wwdg_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = wwdg_reset;
    device_class_set_props(dc, wwdg_properties);
}

static const TypeInfo wwdg_info = {
    .name = TYPE_RIG_STM32_WWDG,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32WwdgState),
    .instance_init = wwdg_init,
    .class_init = wwdg_class_init,
};

static void wwdg_register_types(void) { type_register_static(&wwdg_info); }

type_init(wwdg_register_types)
