/*
 * An STM32F405 GPIO port (A..I), RM0090 section 8.4, or an STM32F411's (A..E, H: RM0383 section 8.4, the
 * same registers; the "chip" property picks the reset values): MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR,
 * BSRR, LCKR and AFRL/AFRH, with each port's own reset values. The port answers only while its clock is on
 * (RCC_AHB1ENR.GPIOxEN), as on the chip: with the clock off, writes are lost and reads give 0.
 *
 * IDR shows the pins: a push-pull output its ODR bit; an open-drain output its ODR bit when 0, else
 * what drives the line from outside, else its pull-up; an alternate-function pin the output of the
 * peripheral its AFR selects (RM0090 8.3.2, the AF multiplexer), taken as an open drain when OTYPER says
 * so, or like an input when that peripheral drives no output there (I2C1, whose bus drives the pins from
 * outside); an input what drives it from outside, else its pull (floating reads 0); an analog pin 0 (its
 * Schmitt trigger is off). The levels go out on 16 qdev GPIO outputs (and again on "level", for SYSCFG's
 * EXTI multiplexer), and 16 qdev GPIO inputs are the
 * outside drivers: the bus and board models connect there. The peripherals connect per pin and AF
 * (line pin * 16 + AF): "af-drive" inputs take their outputs, "af-input" outputs give a pin in AF mode's
 * level to the AF it selects only (a timer's input capture sees its pin only while the pin selects it).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32f4.h"

#define AHB1ENR 0x30

/* RM0090 table 39 (GPIO register map): ports A and B reset with their debug pins configured */
enum { MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFRL, AFRH };
static const RigRegister gpio_registers[] = {
    [MODER] = { 0x00, "MODER", 0, 0xFFFFFFFF },
    [OTYPER] = { 0x04, "OTYPER", 0, 0x0000FFFF },
    [OSPEEDR] = { 0x08, "OSPEEDR", 0, 0xFFFFFFFF },
    [PUPDR] = { 0x0C, "PUPDR", 0, 0xFFFFFFFF },
    [IDR] = { 0x10, "IDR", 0, 0 },
    [ODR] = { 0x14, "ODR", 0, 0x0000FFFF },
    [BSRR] = { 0x18, "BSRR", 0, 0 },
    [LCKR] = { 0x1C, "LCKR", 0, 0x0001FFFF },
    [AFRL] = { 0x20, "AFRL", 0, 0xFFFFFFFF },
    [AFRH] = { 0x24, "AFRH", 0, 0xFFFFFFFF },
};
/* The reset values of ports A and B (index 0, 1), whose debug pins (JTAG/SW-DP) come up as their
 * alternate function; the other ports reset to 0 */
typedef struct GpioDebugResets {
    uint32_t moder[2], ospeedr[2], pupdr[2];
} GpioDebugResets;
/* RM0090 8.4.1, 8.4.3, 8.4.4 (the F405) */
static const GpioDebugResets gpio_f405 = {
    .moder = { 0xA8000000, 0x00000280 },
    .ospeedr = { 0x00000000, 0x000000C0 },
    .pupdr = { 0x64000000, 0x00000100 },
};
/* RM0383 8.4.1, 8.4.3, 8.4.4 (the F411): as the F405's, and PA13 (SWDIO) at very high speed */
static const GpioDebugResets gpio_f411 = {
    .moder = { 0xA8000000, 0x00000280 },
    .ospeedr = { 0x0C000000, 0x000000C0 },
    .pupdr = { 0x64000000, 0x00000100 },
};

#define MODE_INPUT 0u
#define MODE_OUTPUT 1u
#define MODE_AF 2u
#define MODE_ANALOG 3u
#define PULL_UP 1u
#define LCKK (1u << 16)

uint16_t rig_stm32_gpio_levels(RigStm32GpioState *s)
{
    uint16_t levels = 0;
    for (unsigned pin = 0; pin < RIG_GPIO_PINS; pin++) {
        unsigned mode = s->moder >> (2 * pin) & 3, pull = s->pupdr >> (2 * pin) & 3;
        bool odr = s->odr >> pin & 1, open_drain = s->otyper >> pin & 1;
        bool outside = s->ext_driven >> pin & 1, ext = s->ext_level >> pin & 1;
        bool level;
        unsigned af = s->afr[pin / 8] >> (4 * (pin % 8)) & 0xF;
        bool af_drives = mode == MODE_AF && (s->af_driven[af] >> pin & 1);
        bool af_level = s->af_level[af] >> pin & 1;
        if (mode == MODE_ANALOG) {
            level = false;
        } else if (mode == MODE_OUTPUT && (!open_drain || !odr)) {
            level = odr;
        } else if (af_drives && (!open_drain || !af_level)) {
            level = af_level;
        } else {
            level = outside ? ext : pull == PULL_UP;
        }
        levels |= (uint16_t)level << pin;
    }
    return levels;
}

static void gpio_update(RigStm32GpioState *s)
{
    uint16_t levels = rig_stm32_gpio_levels(s);
    uint16_t changed = levels ^ s->pins;
    s->pins = levels;
    for (unsigned pin = 0; pin < RIG_GPIO_PINS; pin++) {
        if (changed >> pin & 1) {
            qemu_set_irq(s->out[pin], levels >> pin & 1);
            qemu_set_irq(s->level[pin], levels >> pin & 1);
        }
    }
    /* a pin in AF mode gives its level to the AF it selects, once per change of either (kept per pin in
     * bytes: the same test on a bit of a uint16_t, a bool != (bool)(x >> pin & 1), is miscompiled by
     * Debian 12's GCC 12.2 at -O2, whose jump threading drops the level's half of it) */
    for (unsigned pin = 0; pin < RIG_GPIO_PINS; pin++) {
        int level = levels >> pin & 1;
        int af = -1;
        if ((s->moder >> (2 * pin) & 3) == MODE_AF) {
            af = (int)(s->afr[pin / 8] >> (4 * (pin % 8)) & 0xF);
        }
        if (af != s->af_input_sent[pin] || level != s->af_input_level[pin]) {
            s->af_input_sent[pin] = (int8_t)af;
            s->af_input_level[pin] = (int8_t)level;
            if (af >= 0) {
                qemu_set_irq(s->af_input[RIG_GPIO_AF_LINE(pin, af)], level);
            }
        }
    }
}

static bool gpio_clocked(RigStm32GpioState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, AHB1ENR, s->port);
}

/* The bits of a register with @width bits per pin that belong to pins locked by LCKR */
static uint32_t locked_bits(const RigStm32GpioState *s, unsigned width, unsigned first_pin)
{
    uint32_t mask = 0;
    if (!(s->lckr & LCKK)) {
        return 0;
    }
    for (unsigned i = 0; i * width < 32 && first_pin + i < RIG_GPIO_PINS; i++) {
        if (s->lckr >> (first_pin + i) & 1) {
            mask |= ((1u << width) - 1) << (i * width);
        }
    }
    return mask;
}

static void set_config(uint32_t *reg, uint32_t value, uint32_t writable, uint32_t locked)
{
    uint32_t mask = writable & ~locked;
    *reg = (*reg & ~mask) | (value & mask);
}

/* RM0090 8.4.8: LCKK=1, LCKK=0, LCKK=1 with the same LCK bits, then a read: the lock holds to reset */
static void lock_write(RigStm32GpioState *s, uint32_t value)
{
    static const uint8_t key[3] = { 1, 0, 1 };
    uint32_t lck = value & 0xFFFF;
    if (s->lckr & LCKK) {
        return;
    }
    if (s->lock_step < 3 && ((value >> 16) & 1) == key[s->lock_step] && (s->lock_step == 0 || lck == s->lock_try)) {
        s->lock_try = lck;
        s->lock_step++;
    } else {
        s->lock_step = 0;
    }
    s->lckr = lck;
}

static uint64_t gpio_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32GpioState *s = opaque;
    if (!gpio_clocked(s)) {
        return 0;
    }
    switch (rig_register_index(gpio_registers, ARRAY_SIZE(gpio_registers), offset)) {
    case MODER:
        return s->moder;
    case OTYPER:
        return s->otyper;
    case OSPEEDR:
        return s->ospeedr;
    case PUPDR:
        return s->pupdr;
    case IDR:
        rig_stm32_timers_sync(false); /* (the pins of the timers whose events wait for a look) */
        return rig_stm32_gpio_levels(s);
    case ODR:
        return s->odr;
    case BSRR:
        return 0; /* write-only */
    case LCKR:
        if (s->lock_step == 3) {
            s->lock_step = 0;
            s->lckr = s->lock_try | LCKK;
        }
        return s->lckr;
    case AFRL:
        return s->afr[0];
    case AFRH:
        return s->afr[1];
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-gpio: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
}

static void gpio_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32GpioState *s = opaque;
    uint32_t v = value;
    if (!gpio_clocked(s)) {
        return;
    }
    switch (rig_register_index(gpio_registers, ARRAY_SIZE(gpio_registers), offset)) {
    case MODER:
        set_config(&s->moder, v, 0xFFFFFFFF, locked_bits(s, 2, 0));
        break;
    case OTYPER:
        set_config(&s->otyper, v, 0xFFFF, locked_bits(s, 1, 0));
        break;
    case OSPEEDR:
        set_config(&s->ospeedr, v, 0xFFFFFFFF, locked_bits(s, 2, 0));
        break;
    case PUPDR:
        set_config(&s->pupdr, v, 0xFFFFFFFF, locked_bits(s, 2, 0));
        break;
    case ODR:
        s->odr = v & 0xFFFF;
        break;
    case BSRR: /* BS wins over BR for the same pin (RM0090 8.4.7) */
        s->odr = ((s->odr & ~(v >> 16)) | v) & 0xFFFF;
        break;
    case LCKR:
        lock_write(s, v);
        break;
    case AFRL:
        set_config(&s->afr[0], v, 0xFFFFFFFF, locked_bits(s, 4, 0));
        break;
    case AFRH:
        set_config(&s->afr[1], v, 0xFFFFFFFF, locked_bits(s, 4, 8));
        break;
    case IDR:
        break; /* read-only */
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-gpio: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    gpio_update(s);
}

static const MemoryRegionOps gpio_ops = {
    .read = gpio_read,
    .write = gpio_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void gpio_drive(void *opaque, int pin, int level)
{
    RigStm32GpioState *s = opaque;
    s->ext_driven |= 1u << pin;
    s->ext_level = (s->ext_level & ~(1u << pin)) | (uint16_t)(level ? 1u << pin : 0);
    gpio_update(s);
}

/* A peripheral's output on @line (pin * 16 + AF): what the pin shows while it selects that AF, unless
 * the peripheral released it (RIG_GPIO_AF_RELEASED) */
static void gpio_af_drive(void *opaque, int line, int level)
{
    RigStm32GpioState *s = opaque;
    unsigned pin = line / RIG_GPIO_AFS, af = line % RIG_GPIO_AFS;
    s->af_driven[af] = (s->af_driven[af] & ~(1u << pin)) | (level == RIG_GPIO_AF_RELEASED ? 0 : 1u << pin);
    s->af_level[af] = (s->af_level[af] & ~(1u << pin)) | (uint16_t)(level ? 1u << pin : 0);
    gpio_update(s);
}

static void gpio_reset(DeviceState *dev)
{
    RigStm32GpioState *s = RIG_STM32_GPIO(dev);
    const GpioDebugResets *r = s->chip == 411 ? &gpio_f411 : &gpio_f405; /* (realize checked it) */
    bool debug = s->port < 2;
    s->moder = debug ? r->moder[s->port] : 0;
    s->otyper = 0;
    s->ospeedr = debug ? r->ospeedr[s->port] : 0;
    s->pupdr = debug ? r->pupdr[s->port] : 0;
    s->odr = 0;
    s->afr[0] = s->afr[1] = 0;
    s->lckr = 0;
    s->lock_step = 0;
    s->lock_try = 0;
    for (unsigned pin = 0; pin < RIG_GPIO_PINS; pin++) {
        s->af_input_sent[pin] = -1;
        s->af_input_level[pin] = -1;
    }
    gpio_update(s);
}

static void gpio_realize(DeviceState *dev, Error **errp)
{
    RigStm32GpioState *s = RIG_STM32_GPIO(dev);
    if (s->chip != 405 && s->chip != 411) {
        error_setg(errp, "rig-stm32f4-gpio: chip %u is not 405 or 411", s->chip);
    }
}

static void gpio_init(Object *obj)
{
    RigStm32GpioState *s = RIG_STM32_GPIO(obj);
    memory_region_init_io(&s->iomem, obj, &gpio_ops, s, TYPE_RIG_STM32_GPIO, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    qdev_init_gpio_out(DEVICE(obj), s->out, RIG_GPIO_PINS);
    qdev_init_gpio_out_named(DEVICE(obj), s->level, "level", RIG_GPIO_PINS);
    qdev_init_gpio_in(DEVICE(obj), gpio_drive, RIG_GPIO_PINS);
    qdev_init_gpio_in_named(DEVICE(obj), gpio_af_drive, "af-drive", RIG_GPIO_PINS * RIG_GPIO_AFS);
    qdev_init_gpio_out_named(DEVICE(obj), s->af_input, "af-input", RIG_GPIO_PINS * RIG_GPIO_AFS);
}

static Property gpio_properties[] = {
    DEFINE_PROP_UINT8("port", RigStm32GpioState, port, 0),
    DEFINE_PROP_UINT32("chip", RigStm32GpioState, chip, 405),
    DEFINE_PROP_LINK("rcc", RigStm32GpioState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void gpio_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = gpio_reset;
    dc->realize = gpio_realize;
    device_class_set_props(dc, gpio_properties);
}

static const TypeInfo gpio_info = {
    .name = TYPE_RIG_STM32_GPIO,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32GpioState),
    .instance_init = gpio_init,
    .class_init = gpio_class_init,
};

static void gpio_register_types(void) { type_register_static(&gpio_info); }

type_init(gpio_register_types)
