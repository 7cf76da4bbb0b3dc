/*
 * The STM32F405's power controller (PWR), RM0090 section 5.4, and the STM32F411's (RM0383 section 5.4:
 * the same two registers, with a two-bit VOS and the F411's low-power bits; the "chip" property picks
 * the table): the regulator's voltage scale (CR.VOS, which 168 MHz and 100 MHz need) and the backup
 * domain's write protection (CR.DBP) read back as written; the backup regulator's ready flag (CSR.BRR)
 * follows its enable (CSR.BRE), and the regulator is ready at the scale asked at once (CSR.VOSRDY stays
 * set: its settling time is not modelled). Its registers answer only while RCC_APB1ENR.PWREN is set, as
 * on the chip. Wake-up, standby, the voltage detector and what the F411's low-power bits (LPLVDS,
 * MRLVDS, ADCDC1, FMSSR, FISSR) do are not modelled (they read back; CSR's flags stay clear).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32f4.h"

#define APB1ENR 0x40
#define APB1ENR_PWREN 28

/* RM0090 table 19 (the F405's PWR register map): CR resets with VOS = 1 (scale 1) */
#define PWR_REGISTERS 2 /* CR, CSR */
static const RigRegister pwr_f405[PWR_REGISTERS] = {
    { 0x00, "CR", 0x00004000, 0x000043F3 },  /* LPDS, PDDS, PVDE, PLS, DBP, FPDS, VOS */
    { 0x04, "CSR", 0x00000000, 0x00000300 }, /* EWUP, BRE */
};
/* RM0383 5.4.1, 5.4.2 (the F411's): CR resets with VOS[15:14] = 10 (scale 2) and adds LPLVDS (10), MRLVDS
 * (11), ADCDC1 (13), FMSSR (20) and FISSR (21); CWUF and CSBF (2, 3) are write-only, read as 0 */
static const RigRegister pwr_f411[PWR_REGISTERS] = {
    { 0x00, "CR", 0x00008000, 0x0030EFF3 },  /* LPDS, PDDS, PVDE, PLS, DBP, FPDS, LPLVDS, MRLVDS, ADCDC1, VOS */
    { 0x04, "CSR", 0x00000000, 0x00000300 }, /* EWUP, BRE */
};
#define CR_CWUF (1u << 2)
#define CR_CSBF (1u << 3)
#define CSR_WUF (1u << 0)
#define CSR_SBF (1u << 1)
#define CSR_BRR (1u << 3)
#define CSR_BRE (1u << 9)
#define CSR_VOSRDY (1u << 14)

static bool pwr_clocked(RigStm32PwrState *s)
{
    return s->rcc == NULL || rig_stm32_rcc_enabled(s->rcc, APB1ENR, APB1ENR_PWREN);
}

static uint64_t pwr_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32PwrState *s = opaque;
    if (!pwr_clocked(s)) {
        return 0;
    }
    switch (rig_register_index(s->table, PWR_REGISTERS, offset)) {
    case 0:
        return s->cr;
    case 1:
        return s->csr;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-pwr: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
}

static void pwr_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32PwrState *s = opaque;
    if (!pwr_clocked(s)) {
        return;
    }
    switch (rig_register_index(s->table, PWR_REGISTERS, offset)) {
    case 0:
        s->cr = (s->cr & ~s->table[0].writable) | ((uint32_t)value & s->table[0].writable);
        if (value & CR_CWUF) {
            s->csr &= ~CSR_WUF;
        }
        if (value & CR_CSBF) {
            s->csr &= ~CSR_SBF;
        }
        break;
    case 1:
        s->csr = (s->csr & ~s->table[1].writable) | ((uint32_t)value & s->table[1].writable);
        s->csr = (s->csr & ~CSR_BRR) | (s->csr & CSR_BRE ? CSR_BRR : 0);
        break;
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-pwr: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
    }
}

static const MemoryRegionOps pwr_ops = {
    .read = pwr_read,
    .write = pwr_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void pwr_reset(DeviceState *dev)
{
    RigStm32PwrState *s = RIG_STM32_PWR(dev);
    s->cr = s->table[0].reset;
    /* the regulator is at its scale from reset on: VOSRDY set */
    s->csr = s->table[1].reset | CSR_VOSRDY;
}

/* The register table of the chip the machine says ("chip": 405 or 411) */
static void pwr_realize(DeviceState *dev, Error **errp)
{
    RigStm32PwrState *s = RIG_STM32_PWR(dev);
    switch (s->chip) {
    case 405:
        s->table = pwr_f405;
        break;
    case 411:
        s->table = pwr_f411;
        break;
    default:
        error_setg(errp, "rig-stm32f4-pwr: chip %u is not 405 or 411", s->chip);
    }
}

static void pwr_init(Object *obj)
{
    RigStm32PwrState *s = RIG_STM32_PWR(obj);
    memory_region_init_io(&s->iomem, obj, &pwr_ops, s, TYPE_RIG_STM32_PWR, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
}

static Property pwr_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32PwrState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_UINT32("chip", RigStm32PwrState, chip, 405),
    DEFINE_PROP_END_OF_LIST(),
};

static void pwr_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = pwr_reset;
    dc->realize = pwr_realize;
    device_class_set_props(dc, pwr_properties);
}

static const TypeInfo pwr_info = {
    .name = TYPE_RIG_STM32_PWR,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32PwrState),
    .instance_init = pwr_init,
    .class_init = pwr_class_init,
};

static void pwr_register_types(void) { type_register_static(&pwr_info); }

type_init(pwr_register_types)
