/*
 * The STM32F405's external interrupts from its pins: SYSCFG (RM0090 section 9.2), whose EXTICR1..4 pick
 * the port each EXTI line 0..15 follows (line n: pin n of port A..I), and the EXTI controller (section
 * 12.3): an edge the line's RTSR/FTSR bit selects sets its PR bit, as does writing 1 to its SWIER bit;
 * PR is cleared by writing 1 (which clears SWIER too), and the line's NVIC input is high while a PR bit
 * it unmasks (IMR) is set, so a handler that does not clear PR is entered again, as on the chip. The
 * lines 5..9 and 10..15 share one NVIC input each (RM0090 table 61), ORed here.
 *
 * QEMU 7.2's SoC has SYSCFG and EXTI models at these addresses, mapped over here: its SYSCFG takes the
 * pins of port A only (a pin of port B..I selects a register past EXTICR4 and aborts QEMU), and its EXTI
 * raises the NVIC line on any change of an unmasked line, whatever edge RTSR/FTSR select, and has no
 * software trigger.
 *
 * SYSCFG answers only while RCC_APB2ENR.SYSCFGEN is set and is reset by RCC_APB2RSTR.SYSCFGRST; EXTI has
 * no clock enable. The lines 16..22 (PVD, RTC, USB and Ethernet wake-ups) have no source here: only
 * SWIER sets their PR bits. Events (EMR: a pulse for WFE) are stored, not generated.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32f4.h"

#define APB2ENR 0x44
#define APB2ENR_SYSCFGEN 14

/* RM0090 table 35 (SYSCFG register map): MEMRMP reads the boot mode, main flash (0) here */
enum { MEMRMP, PMC, EXTICR1, EXTICR2, EXTICR3, EXTICR4, CMPCR };
static const RigRegister syscfg_registers[] = {
    [MEMRMP] = { 0x00, "MEMRMP", 0, 0x00000003 },   [PMC] = { 0x04, "PMC", 0, 0x00800000 },
    [EXTICR1] = { 0x08, "EXTICR1", 0, 0x0000FFFF }, [EXTICR2] = { 0x0C, "EXTICR2", 0, 0x0000FFFF },
    [EXTICR3] = { 0x10, "EXTICR3", 0, 0x0000FFFF }, [EXTICR4] = { 0x14, "EXTICR4", 0, 0x0000FFFF },
    [CMPCR] = { 0x20, "CMPCR", 0, 0x00000001 },
};
#define CMPCR_CMP_PD 1u
#define CMPCR_READY (1u << 8)

/* RM0090 table 50 (EXTI register map): the 23 lines' bits */
enum { IMR, EMR, RTSR, FTSR, SWIER, PR };
#define LINES_MASK 0x007FFFFFu
static const RigRegister exti_registers[] = {
    [IMR] = { 0x00, "IMR", 0, LINES_MASK },     [EMR] = { 0x04, "EMR", 0, LINES_MASK },
    [RTSR] = { 0x08, "RTSR", 0, LINES_MASK },   [FTSR] = { 0x0C, "FTSR", 0, LINES_MASK },
    [SWIER] = { 0x10, "SWIER", 0, LINES_MASK }, [PR] = { 0x14, "PR", 0, LINES_MASK },
};

/* RM0090 table 61: each line's NVIC input, numbered as the EXTI's outputs (RIG_EXTI_IRQS of them) */
static const uint8_t line_irq[RIG_EXTI_LINES] = {
    0, 1, 2, 3,  4,     /* EXTI0..EXTI4 */
    5, 5, 5, 5,  5,     /* EXTI9_5 */
    6, 6, 6, 6,  6,  6, /* EXTI15_10 */
    7, 8, 9, 10, 11, 12, 13,
};
const uint8_t rig_exti_nvic[RIG_EXTI_IRQS] = {
    6, 7,  8,  9,  10, 23, 40, /* EXTI0..4, EXTI9_5, EXTI15_10 */
    1, 41, 42, 62, 76, 2,  3,  /* PVD, RTC_Alarm, OTG_FS_WKUP, ETH_WKUP, OTG_HS_WKUP, TAMP_STAMP, RTC_WKUP */
};

/* ---- SYSCFG ---- */

static bool syscfg_clocked(RigStm32SyscfgState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, APB2ENR, APB2ENR_SYSCFGEN);
}

/* Each line 0..15 the level of the pin EXTICR selects for it, sent to EXTI when it changes */
static void syscfg_route(RigStm32SyscfgState *s)
{
    for (unsigned line = 0; line < RIG_GPIO_PINS; line++) {
        unsigned port = s->regs[EXTICR1 + line / 4] >> (4 * (line % 4)) & 0xF;
        /* (EXTIx values past port I are reserved: the line then follows nothing) */
        int level = port < RIG_GPIO_PORTS ? s->pins[port] >> line & 1 : 0;
        if (level != s->line_level[line]) {
            s->line_level[line] = (int8_t)level;
            qemu_set_irq(s->line[line], level);
        }
    }
}

static void syscfg_pin(void *opaque, int n, int level)
{
    RigStm32SyscfgState *s = opaque;
    unsigned port = n / RIG_GPIO_PINS, pin = n % RIG_GPIO_PINS;
    s->pins[port] = (s->pins[port] & ~(1u << pin)) | (uint16_t)(level ? 1u << pin : 0);
    syscfg_route(s);
}

static uint64_t syscfg_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32SyscfgState *s = opaque;
    int i = rig_register_index(syscfg_registers, ARRAY_SIZE(syscfg_registers), offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-syscfg: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    if (!syscfg_clocked(s)) {
        return 0;
    }
    /* the compensation cell is ready as soon as it is powered (RM0090 9.2.8) */
    return i == CMPCR && (s->regs[CMPCR] & CMPCR_CMP_PD) ? s->regs[i] | CMPCR_READY : s->regs[i];
}

static void syscfg_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32SyscfgState *s = opaque;
    int i = rig_register_index(syscfg_registers, ARRAY_SIZE(syscfg_registers), offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-syscfg: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    if (!syscfg_clocked(s)) {
        return;
    }
    if (i == MEMRMP && (value & 3) != (s->regs[MEMRMP] & 3)) {
        qemu_log_mask(LOG_UNIMP, "rig-stm32f4-syscfg: MEMRMP: remapping memory at 0 is not modelled\n");
    }
    s->regs[i] = (uint32_t)value & syscfg_registers[i].writable;
    syscfg_route(s);
}

static const MemoryRegionOps syscfg_ops = {
    .read = syscfg_read,
    .write = syscfg_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

/* The registers to their reset values; the pins' levels are the wires' and stay */
static void syscfg_reset(DeviceState *dev)
{
    RigStm32SyscfgState *s = RIG_STM32_SYSCFG(dev);
    for (unsigned i = 0; i < ARRAY_SIZE(syscfg_registers); i++) {
        s->regs[i] = syscfg_registers[i].reset;
    }
    syscfg_route(s);
}

static void syscfg_init(Object *obj)
{
    RigStm32SyscfgState *s = RIG_STM32_SYSCFG(obj);
    memory_region_init_io(&s->iomem, obj, &syscfg_ops, s, TYPE_RIG_STM32_SYSCFG, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    qdev_init_gpio_in_named(DEVICE(obj), syscfg_pin, "pin", RIG_GPIO_PORTS * RIG_GPIO_PINS);
    qdev_init_gpio_out_named(DEVICE(obj), s->line, "line", RIG_GPIO_PINS);
}

static Property syscfg_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32SyscfgState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void syscfg_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = syscfg_reset;
    device_class_set_props(dc, syscfg_properties);
}

/* ---- EXTI ---- */

/* The machine's EXTI, for rig_stm32_exti_watches_pins() */
static RigStm32ExtiState *the_exti;

bool rig_stm32_exti_watches_pins(void)
{
    return the_exti != NULL && ((the_exti->regs[RTSR] | the_exti->regs[FTSR]) & 0xFFFF);
}

static void exti_update(RigStm32ExtiState *s)
{
    uint32_t raised = s->regs[PR] & s->regs[IMR];
    for (unsigned k = 0; k < RIG_EXTI_IRQS; k++) {
        bool level = false;
        for (unsigned line = 0; line < RIG_EXTI_LINES; line++) {
            level |= line_irq[line] == k && (raised >> line & 1);
        }
        qemu_set_irq(s->irq[k], level);
    }
}

/* Line @line's input now at @level: an edge its trigger registers select sets its pending bit */
static void exti_line(void *opaque, int line, int level)
{
    RigStm32ExtiState *s = opaque;
    bool was = s->inputs >> line & 1;
    s->inputs = (s->inputs & ~(1u << line)) | (level ? 1u << line : 0);
    if ((level && !was && (s->regs[RTSR] >> line & 1)) || (!level && was && (s->regs[FTSR] >> line & 1))) {
        s->regs[PR] |= 1u << line;
        exti_update(s);
    }
}

static uint64_t exti_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32ExtiState *s = opaque;
    int i = rig_register_index(exti_registers, ARRAY_SIZE(exti_registers), offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-exti: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    return s->regs[i];
}

static void exti_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32ExtiState *s = opaque;
    int i = rig_register_index(exti_registers, ARRAY_SIZE(exti_registers), offset);
    uint32_t v = (uint32_t)value & LINES_MASK;
    bool watched = rig_stm32_exti_watches_pins();
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-exti: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    if (i == PR) { /* rc_w1: clears the pending bits written 1, and their SWIER bits (RM0090 12.3.5) */
        s->regs[PR] &= ~v;
        s->regs[SWIER] &= ~v;
    } else if (i == SWIER) { /* a 1 written where SWIER is 0 sets the pending bit */
        s->regs[PR] |= v & ~s->regs[SWIER];
        s->regs[SWIER] |= v;
    } else {
        s->regs[i] = v;
    }
    exti_update(s);
    if (rig_stm32_exti_watches_pins() != watched) { /* (the timers' pins: edges at their instants, or not) */
        rig_stm32_timers_sync(true);
    }
}

static const MemoryRegionOps exti_ops = {
    .read = exti_read,
    .write = exti_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void exti_reset(DeviceState *dev)
{
    RigStm32ExtiState *s = RIG_STM32_EXTI(dev);
    for (unsigned i = 0; i < ARRAY_SIZE(exti_registers); i++) {
        s->regs[i] = exti_registers[i].reset;
    }
    exti_update(s);
}

static void exti_init(Object *obj)
{
    RigStm32ExtiState *s = RIG_STM32_EXTI(obj);
    memory_region_init_io(&s->iomem, obj, &exti_ops, s, TYPE_RIG_STM32_EXTI, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    qdev_init_gpio_in_named(DEVICE(obj), exti_line, "line", RIG_EXTI_LINES);
    for (unsigned k = 0; k < RIG_EXTI_IRQS; k++) {
        sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq[k]);
    }
}

static void exti_realize(DeviceState *dev, Error **errp) { the_exti = RIG_STM32_EXTI(dev); }

static void exti_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = exti_reset;
    dc->realize = exti_realize;
}

static const TypeInfo exti_types[] = {
    {
        .name = TYPE_RIG_STM32_SYSCFG,
        .parent = TYPE_SYS_BUS_DEVICE,
        .instance_size = sizeof(RigStm32SyscfgState),
        .instance_init = syscfg_init,
        .class_init = syscfg_class_init,
    },
    {
        .name = TYPE_RIG_STM32_EXTI,
        .parent = TYPE_SYS_BUS_DEVICE,
        .instance_size = sizeof(RigStm32ExtiState),
        .instance_init = exti_init,
        .class_init = exti_class_init,
    },
};

DEFINE_TYPES(exti_types)
