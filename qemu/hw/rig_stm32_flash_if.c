/*
 * The STM32F405's FLASH interface registers, RM0090 section 3.9: ACR (wait states, which 168 MHz needs
 * five of, read back as written: HAL checks them), and the CR lock with its key sequence (KEY1 then
 * KEY2 to KEYR unlocks CR; a wrong key locks it until reset; CR.LOCK written 1 locks it again).
 * Programming and erasing the flash are not modelled yet: CR's PG, SER and STRT are stored, SR stays 0.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32f4.h"

/* RM0090 table 12 (FLASH interface register map) */
enum { ACR, KEYR, OPTKEYR, SR, CR, OPTCR };
static const RigRegister flash_registers[] = {
    [ACR] = { 0x00, "ACR", 0x00000000, 0x00000707 }, /* LATENCY[2:0], PRFTEN, ICEN, DCEN */
    [KEYR] = { 0x04, "KEYR", 0x00000000, 0x00000000 },   [OPTKEYR] = { 0x08, "OPTKEYR", 0x00000000, 0x00000000 },
    [SR] = { 0x0C, "SR", 0x00000000, 0x000000F3 }, /* EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR: w1c */
    [CR] = { 0x10, "CR", 0x80000000, 0x0301037F }, /* PG, SER, MER, SNB, PSIZE, STRT, EOPIE, ERRIE */
    [OPTCR] = { 0x14, "OPTCR", 0x0FFFAAED, 0x00000000 },
};
#define KEY1 0x45670123u
#define KEY2 0xCDEF89ABu
#define CR_LOCK (1u << 31)

static uint64_t flash_if_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32FlashIfState *s = opaque;
    switch (rig_register_index(flash_registers, ARRAY_SIZE(flash_registers), offset)) {
    case ACR:
        return s->acr;
    case SR:
        return s->sr;
    case CR:
        return s->cr;
    case OPTCR:
        return s->optcr;
    case KEYR:
    case OPTKEYR:
        return 0; /* write-only */
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-flash-if: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
}

static void flash_if_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32FlashIfState *s = opaque;
    uint32_t v = value;
    switch (rig_register_index(flash_registers, ARRAY_SIZE(flash_registers), offset)) {
    case ACR:
        /* ICRST and DCRST (bits 11, 12) reset the caches, which are not modelled; they read 0 */
        s->acr = v & flash_registers[ACR].writable;
        break;
    case KEYR:
        if (!(s->cr & CR_LOCK) || s->locked_out) {
            break;
        }
        if (s->key_step == 0 && v == KEY1) {
            s->key_step = 1;
        } else if (s->key_step == 1 && v == KEY2) {
            s->key_step = 0;
            s->cr &= ~CR_LOCK;
        } else {
            s->locked_out = true; /* RM0090 3.5.1: a wrong sequence locks until the next reset */
        }
        break;
    case SR:
        s->sr &= ~(v & flash_registers[SR].writable);
        break;
    case CR:
        if (s->cr & CR_LOCK) {
            break;
        }
        s->cr = (v & flash_registers[CR].writable) | (v & CR_LOCK);
        break;
    case OPTKEYR:
    case OPTCR:
        break; /* option bytes: not modelled */
    default:
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-flash-if: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
    }
}

static const MemoryRegionOps flash_if_ops = {
    .read = flash_if_read,
    .write = flash_if_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

static void flash_if_reset(DeviceState *dev)
{
    RigStm32FlashIfState *s = RIG_STM32_FLASH_IF(dev);
    s->acr = flash_registers[ACR].reset;
    s->sr = flash_registers[SR].reset;
    s->cr = flash_registers[CR].reset;
    s->optcr = flash_registers[OPTCR].reset;
    s->key_step = 0;
    s->locked_out = false;
}

static void flash_if_init(Object *obj)
{
    RigStm32FlashIfState *s = RIG_STM32_FLASH_IF(obj);
    memory_region_init_io(&s->iomem, obj, &flash_if_ops, s, TYPE_RIG_STM32_FLASH_IF, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
}

static void flash_if_class_init(ObjectClass *klass, void *data) { DEVICE_CLASS(klass)->reset = flash_if_reset; }

static const TypeInfo flash_if_info = {
    .name = TYPE_RIG_STM32_FLASH_IF,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32FlashIfState),
    .instance_init = flash_if_init,
    .class_init = flash_if_class_init,
};

static void flash_if_register_types(void) { type_register_static(&flash_if_info); }

type_init(flash_if_register_types)
