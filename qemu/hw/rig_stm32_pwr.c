/*
 * The STM32F405's power controller (PWR), RM0090 section 5.4: the regulator's voltage scale (CR.VOS,
 * which 168 MHz needs) and the backup domain's write protection (CR.DBP); the backup regulator's ready
 * flag (CSR.BRR) follows its enable (CSR.BRE). Its registers answer only while RCC_APB1ENR.PWREN is set,
 * as on the chip. Wake-up, standby and the voltage detector are not modelled (CSR's flags stay clear).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/qdev-properties.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32f4.h"

#define APB1ENR 0x40
#define APB1ENR_PWREN 28

/* RM0090 table 19 (PWR register map): CR resets with VOS = 1 (scale 1) */
static const RigRegister pwr_registers[] = {
    { 0x00, "CR", 0x00004000, 0x000043F3 },  /* LPDS, PDDS, PVDE, PLS, DBP, FPDS, VOS */
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
    switch (rig_register_index(pwr_registers, ARRAY_SIZE(pwr_registers), offset)) {
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
    switch (rig_register_index(pwr_registers, ARRAY_SIZE(pwr_registers), offset)) {
    case 0:
        s->cr = (s->cr & ~pwr_registers[0].writable) | ((uint32_t)value & pwr_registers[0].writable);
        if (value & CR_CWUF) {
            s->csr &= ~CSR_WUF;
        }
        if (value & CR_CSBF) {
            s->csr &= ~CSR_SBF;
        }
        break;
    case 1:
        s->csr = (s->csr & ~pwr_registers[1].writable) | ((uint32_t)value & pwr_registers[1].writable);
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
    s->cr = pwr_registers[0].reset;
    /* the regulator is at its scale from reset on: VOSRDY set */
    s->csr = pwr_registers[1].reset | CSR_VOSRDY;
}

static void pwr_init(Object *obj)
{
    RigStm32PwrState *s = RIG_STM32_PWR(obj);
    memory_region_init_io(&s->iomem, obj, &pwr_ops, s, TYPE_RIG_STM32_PWR, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
}

static Property pwr_properties[] = {
    DEFINE_PROP_LINK("rcc", RigStm32PwrState, rcc, TYPE_RIG_STM32_RCC, RigStm32RccState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void pwr_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = pwr_reset;
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
