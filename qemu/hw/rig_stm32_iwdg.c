/*
 * The STM32F405's independent watchdog (IWDG), RM0090 section 19: KR's keys (0xCCCC starts it, 0xAAAA
 * reloads the down-counter from RLR, 0x5555 opens PR and RLR to writes until the next other key), PR
 * (the LSI divided by 4 * 2^PR, at most 256), RLR, and SR's PVU and RVU, busy while a written PR or RLR
 * crosses into the watchdog's voltage domain: five LSI cycles (19.4.4), during which a new value is
 * ignored. The counter runs on the LSI at its nominal 32 kHz in virtual time; reaching 0 it resets the
 * system with RCC_CSR.IWDGRSTF set. Once started, only a reset stops it. Its counter is not readable, so
 * the model keeps only when it runs out: (RLR + 1) ticks of 4 * 2^PR LSI cycles after the last reload,
 * with PR and RLR as they are at that reload. The hardware watchdog option (WDG_SW) and the debug
 * freeze (DBGMCU) are not modelled.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/qdev-properties.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"

/* RM0090 table 108 (IWDG register map) */
enum { KR, PR, RLR, SR };
static const RigRegister iwdg_registers[] = {
    [KR] = { 0x00, "KR", 0x00000000, 0x0000FFFF },
    [PR] = { 0x04, "PR", 0x00000000, 0x00000007 },
    [RLR] = { 0x08, "RLR", 0x00000FFF, 0x00000FFF },
    [SR] = { 0x0C, "SR", 0x00000000, 0x00000000 },
};
#define KEY_ACCESS 0x5555u
#define KEY_RELOAD 0xAAAAu
#define KEY_START 0xCCCCu
#define SR_PVU (1u << 0)
#define SR_RVU (1u << 1)
#define RCC_CSR_IWDGRSTF (1u << 29)
/* the LSI's nominal 32 kHz (DS8626): one cycle in ns */
#define LSI_NS 31250
#define UPDATE_LSI_CYCLES 5

static void iwdg_reload(RigStm32IwdgState *s)
{
    int64_t ticks = (int64_t)(s->rlr + 1) * (4 << MIN(s->pr, 6u));
    timer_mod(s->timer, qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL) + ticks * LSI_NS);
}

static void iwdg_expire(void *opaque)
{
    RigStm32IwdgState *s = opaque;
    rig_stm32_rcc_watchdog_reset(s->rcc, RCC_CSR_IWDGRSTF, RIG_RESET_IWDG);
}

static uint64_t iwdg_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32IwdgState *s = opaque;
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    switch (rig_register_index(iwdg_registers, ARRAY_SIZE(iwdg_registers), offset)) {
    case KR:
        return 0; /* write-only */
    case PR:
        return s->pr;
    case RLR:
        return s->rlr;
    case SR:
        return (now < s->pvu_until_ns ? SR_PVU : 0) | (now < s->rvu_until_ns ? SR_RVU : 0);
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-iwdg: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
}

/* A write of PR or RLR: taken when they are open and no update of the register is under way */
static void iwdg_update(RigStm32IwdgState *s, uint32_t *reg, int64_t *until_ns, uint32_t value, const char *name)
{
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    if (!s->unlocked || now < *until_ns) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-iwdg: %s written %s: ignored\n", name,
                      s->unlocked ? "while its update is under way" : "without the 0x5555 key");
        return;
    }
    *reg = value;
    *until_ns = now + UPDATE_LSI_CYCLES * LSI_NS;
}

static void iwdg_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32IwdgState *s = opaque;
    uint32_t v = value;
    int i = rig_register_index(iwdg_registers, ARRAY_SIZE(iwdg_registers), offset);
    switch (i) {
    case KR:
        v &= iwdg_registers[KR].writable;
        s->unlocked = v == KEY_ACCESS; /* any other key closes PR and RLR again */
        if (v == KEY_START) {
            s->running = true;
        }
        if (s->running && (v == KEY_START || v == KEY_RELOAD)) {
            iwdg_reload(s);
        }
        break;
    case PR:
    case RLR:
        iwdg_update(s, i == PR ? &s->pr : &s->rlr, i == PR ? &s->pvu_until_ns : &s->rvu_until_ns,
                    v & iwdg_registers[i].writable, iwdg_registers[i].name);
        break;
    case SR:
        break; /* read-only */
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-iwdg: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
    }
}

static const MemoryRegionOps iwdg_ops = {
    .read = iwdg_read,
    .write = iwdg_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void iwdg_reset(DeviceState *dev)
{
    RigStm32IwdgState *s = RIG_STM32_IWDG(dev);
    s->pr = iwdg_registers[PR].reset;
    s->rlr = iwdg_registers[RLR].reset;
    s->running = false;
    s->unlocked = false;
    s->pvu_until_ns = 0;
    s->rvu_until_ns = 0;
    timer_del(s->timer);
}

static void iwdg_init(Object *obj)
{
    RigStm32IwdgState *s = RIG_STM32_IWDG(obj);
    memory_region_init_io(&s->iomem, obj, &iwdg_ops, s, TYPE_RIG_STM32_IWDG, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    s->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, iwdg_expire, s);
}

static Property iwdg_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32IwdgState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void iwdg_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = iwdg_reset;
    device_class_set_props(dc, iwdg_properties);
}

static const TypeInfo iwdg_info = {
    .name = TYPE_RIG_STM32_IWDG,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32IwdgState),
    .instance_init = iwdg_init,
    .class_init = iwdg_class_init,
};

static void iwdg_register_types(void) { type_register_static(&iwdg_info); }

type_init(iwdg_register_types)
