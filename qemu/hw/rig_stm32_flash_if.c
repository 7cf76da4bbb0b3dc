/*
 * The STM32F405's FLASH interface, RM0090 section 3, and the STM32F411's (RM0383 section 3: its 512 KB in
 * 8 sectors, its datasheet's erase times; the "chip" property picks the table): ACR (wait states, which
 * 168 MHz needs five of, read back as written: HAL checks them), the CR lock with its key sequence (KEY1 then KEY2 to KEYR unlocks
 * CR; a wrong key locks it until reset; CR.LOCK written 1 locks it again), and programming and erasing
 * the main flash (3.5-3.7): sector erase (SER, SNB, STRT) of the chip's sectors (RM0090 table 5, RM0383 table 4) and mass erase
 * (MER) to 0xFF, and programming by a write to a flash address while CR.PG is set, in the size PSIZE
 * gives (x8, x16, x32); a cell only goes from 1 to 0 (a write ANDs). SR's error flags PGSERR and PGPERR
 * as 3.9.4 sets them, BSY for the datasheet's typical time of the operation in virtual time,
 * then EOP (only with EOPIE, as 3.9.4 says) and the FLASH interrupt.
 *
 * The flash itself is this device's second MMIO region, a ROM device mapped over the SoC's ROM (at
 * 0x08000000 and its alias at 0): the core reads and executes from its RAM at full speed, and its
 * writes come here. QEMU's loader writes the image into a ROM once, but into anything else again at each
 * reset (which would undo what the firmware programmed): so the cells stay disabled while the loader
 * looks and writes, the image goes into the SoC's ROM (erased to 0xFF first), and when the machine
 * first starts the cells take the ROM's contents and its place.
 * An operation is done at once and BSY only times it: on the chip a read of the flash during an operation
 * stalls the bus until the end; here it returns the new data at once. An operation started while one is
 * under way (the chip would stall the write) is queued after it: BSY lasts for both.
 * Option bytes (OPTCR, write protection: WRPERR) and the OTP area are not modelled.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"
#include "sysemu/runstate.h"

/* The FLASH interface's registers (RM0090 3.9 and table 12, RM0383 3.8) */
enum { ACR, KEYR, OPTKEYR, SR, CR, OPTCR, FLASH_REGISTERS };

/* What differs between the chips: the registers' reset values and writable bits, the main flash's sectors
 * (4 x 16 KB, one of 64 KB, then 128 KB each: sector_start) and the datasheet's typical erase times */
typedef struct RigFlashChip {
    RigRegister registers[FLASH_REGISTERS];
    unsigned sectors;
    int64_t erase_ns[3][3];   /* a sector of 16, 64 and 128 KB, with PSIZE x8, x16 and x32 (x64 as x32) */
    int64_t mass_erase_ns[3]; /* MER, with PSIZE x8, x16 and x32 */
} RigFlashChip;

#define MS(n) ((int64_t)(n)*SCALE_MS)
/* The F405: RM0090 table 12's registers and table 5's 12 sectors (1 MB); DS8626's typical erase times
 * (its flash programming table gives one for the three parallelisms) */
static const RigFlashChip flash_f405 = {
    .registers = {
        [ACR] = { 0x00, "ACR", 0x00000000, 0x00000707 }, /* LATENCY[2:0], PRFTEN, ICEN, DCEN */
        [KEYR] = { 0x04, "KEYR", 0x00000000, 0x00000000 },
        [OPTKEYR] = { 0x08, "OPTKEYR", 0x00000000, 0x00000000 },
        [SR] = { 0x0C, "SR", 0x00000000, 0x000000F3 }, /* EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR: w1c */
        [CR] = { 0x10, "CR", 0x80000000, 0x0301037F }, /* PG, SER, MER, SNB[3:0], PSIZE, STRT (below), EOPIE, ERRIE */
        [OPTCR] = { 0x14, "OPTCR", 0x0FFFAAED, 0x00000000 },
    },
    .sectors = 12,
    .erase_ns = { { MS(400), MS(400), MS(400) }, { MS(1200), MS(1200), MS(1200) }, { MS(2000), MS(2000), MS(2000) } },
    .mass_erase_ns = { MS(16000), MS(16000), MS(16000) },
};
/* The F411: RM0383 3.8's registers (ACR's LATENCY is three bits as the F405's, ST's stm32f411xe.h masks it
 * 0x7, where the F42x's and F446's have four; SR adds RDERR, bit 8, for PCROP reads; OPTCR resets to the
 * same value) and 3.3's 8 sectors (table 4: 512 KB); DS10314's typical erase times
 * (its flash memory programming table), which shorten as the parallelism (PSIZE) widens */
static const RigFlashChip flash_f411 = {
    .registers = {
        [ACR] = { 0x00, "ACR", 0x00000000, 0x00000707 }, /* LATENCY[2:0], PRFTEN, ICEN, DCEN */
        [KEYR] = { 0x04, "KEYR", 0x00000000, 0x00000000 },
        [OPTKEYR] = { 0x08, "OPTKEYR", 0x00000000, 0x00000000 },
        [SR] = { 0x0C, "SR", 0x00000000, 0x000001F3 }, /* the F405's and RDERR: w1c */
        [CR] = { 0x10, "CR", 0x80000000, 0x0301037F }, /* as the F405's: SNB[3:0], of which 0-7 are sectors */
        [OPTCR] = { 0x14, "OPTCR", 0x0FFFAAED, 0x00000000 },
    },
    .sectors = 8,
    .erase_ns = { { MS(400), MS(300), MS(250) }, { MS(1200), MS(700), MS(550) }, { MS(2000), MS(1300), MS(1000) } },
    .mass_erase_ns = { MS(8000), MS(5500), MS(4000) },
};
#define KEY1 0x45670123u
#define KEY2 0xCDEF89ABu
#define CR_LOCK (1u << 31)
#define CR_PG (1u << 0)
#define CR_SER (1u << 1)
#define CR_MER (1u << 2)
#define CR_SNB_SHIFT 3
#define CR_PSIZE_SHIFT 8
#define CR_STRT (1u << 16)
#define CR_EOPIE (1u << 24)
#define CR_ERRIE (1u << 25)
#define SR_EOP (1u << 0)
#define SR_OPERR (1u << 1)
#define SR_PGPERR (1u << 6)
#define SR_PGSERR (1u << 7)
#define SR_BSY (1u << 16)

/* RM0090 table 5, RM0383 table 4: the main flash's sectors, 4 x 16 KB, 64 KB, then 128 KB each */
static hwaddr sector_start(unsigned n) { return n < 4 ? n * 0x4000 : n == 4 ? 0x10000 : (n - 4) * 0x20000; }
static hwaddr sector_size(unsigned n) { return n < 4 ? 0x4000 : n == 4 ? 0x10000 : 0x20000; }

/* DS8626 and DS10314, flash memory programming: a word's typical programming time on both chips */
#define PROGRAM_NS (16 * SCALE_US)

static void flash_irq_update(RigStm32FlashIfState *s)
{
    bool eop = (s->sr & SR_EOP) && (s->cr & CR_EOPIE), err = (s->sr & SR_OPERR) && (s->cr & CR_ERRIE);
    qemu_set_irq(s->irq, eop || err);
}

/* BSY for @ns more, after the operation under way if there is one */
static void flash_busy(RigStm32FlashIfState *s, int64_t ns)
{
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    s->busy_until_ns = MAX(s->busy_until_ns, now) + ns;
    s->sr |= SR_BSY;
    timer_mod(s->busy, s->busy_until_ns);
}

/* The end of the operation: BSY and STRT clear, EOP (3.9.4: only when EOPIE is set) */
static void flash_done(void *opaque)
{
    RigStm32FlashIfState *s = opaque;
    s->sr &= ~SR_BSY;
    s->cr &= ~CR_STRT;
    if (s->cr & CR_EOPIE) {
        s->sr |= SR_EOP;
    }
    flash_irq_update(s);
}

/* The cells from @start, @size bytes, erased to 0xFF */
static void flash_erase(RigStm32FlashIfState *s, hwaddr start, hwaddr size)
{
    memset((uint8_t *)memory_region_get_ram_ptr(&s->cells) + start, 0xFF, size);
    memory_region_flush_rom_device(&s->cells, start, size);
}

/* CR.STRT: a sector erase (SER and SNB) or a mass erase (MER) */
static void flash_start(RigStm32FlashIfState *s)
{
    const RigFlashChip *part = s->part;
    unsigned snb = s->cr >> CR_SNB_SHIFT & 0xF, psize = MIN(s->cr >> CR_PSIZE_SHIFT & 0x3, 2u);
    if (s->cr & CR_MER) {
        flash_erase(s, 0, sector_start(part->sectors));
        flash_busy(s, part->mass_erase_ns[psize]);
    } else if ((s->cr & CR_SER) && snb < part->sectors) {
        flash_erase(s, sector_start(snb), sector_size(snb));
        flash_busy(s, part->erase_ns[snb < 4 ? 0 : snb == 4 ? 1 : 2][psize]);
    } else {
        /* RM0090 3.9.5 and RM0383 3.8.5 call other SNB values "not allowed" and name no flag for them: the
         * erase does not start, nothing is erased, SR stays as it was */
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-flash-if: STRT without MER, or SER with sector %u (of 0..%u)\n",
                      snb, part->sectors - 1);
        s->cr &= ~CR_STRT;
    }
}

/* The core reads the cells from their RAM (ROMD mode); this only answers other readers */
static uint64_t flash_cells_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32FlashIfState *s = opaque;
    return ldn_le_p((uint8_t *)memory_region_get_ram_ptr(&s->cells) + offset, size);
}

/* A write to the flash: a program operation (RM0090 3.5.4), or an error flag */
static void flash_cells_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32FlashIfState *s = opaque;
    unsigned psize = s->cr >> CR_PSIZE_SHIFT & 0x3;
    uint32_t error = 0;
    if ((s->cr & CR_LOCK) || !(s->cr & CR_PG)) {
        error = SR_PGSERR; /* a write to the flash without the program sequence set up */
    } else if (size != 1u << psize) {
        /* the access's size is not PSIZE's; the core splits a misaligned access into bytes (ARMv7-M A3.2.1,
         * QEMU likewise), so it lands here too, and PGAERR (a row crossed: x64 only) never comes */
        error = SR_PGPERR;
    }
    if (error) {
        qemu_log_mask(LOG_GUEST_ERROR,
                      "rig-stm32f4-flash-if: a %u-byte write to flash offset 0x%" HWADDR_PRIx
                      " with CR 0x%08x: SR 0x%02x\n",
                      size, offset, s->cr, error);
        s->sr |= error;
        return;
    }
    uint8_t *cells = (uint8_t *)memory_region_get_ram_ptr(&s->cells) + offset;
    for (unsigned i = 0; i < size; i++) {
        cells[i] &= (uint8_t)(value >> (8 * i)); /* programming only clears bits */
    }
    memory_region_flush_rom_device(&s->cells, offset, size);
    flash_busy(s, PROGRAM_NS);
}

static const MemoryRegionOps flash_cells_ops = {
    .read = flash_cells_read,
    .write = flash_cells_write,
    .endianness = DEVICE_LITTLE_ENDIAN,
    .valid.min_access_size = 1,
    .valid.max_access_size = 4,
    .impl.min_access_size = 1,
    .impl.max_access_size = 4,
};

static uint64_t flash_if_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32FlashIfState *s = opaque;
    switch (rig_register_index(s->part->registers, FLASH_REGISTERS, offset)) {
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
    switch (rig_register_index(s->part->registers, FLASH_REGISTERS, offset)) {
    case ACR:
        /* ICRST and DCRST (bits 11, 12) reset the caches, which are not modelled; they read 0 */
        s->acr = v & s->part->registers[ACR].writable;
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
        s->sr &= ~(v & s->part->registers[SR].writable);
        flash_irq_update(s);
        break;
    case CR:
        if (s->cr & CR_LOCK) {
            break;
        }
        /* STRT is set by software and cleared only by the hardware at the end of the erase */
        s->cr = (v & s->part->registers[CR].writable) | (v & CR_LOCK) | (s->cr & CR_STRT);
        if ((v & CR_STRT) && !(s->sr & SR_BSY)) {
            flash_start(s);
        }
        flash_irq_update(s);
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
    s->acr = s->part->registers[ACR].reset;
    s->sr = s->part->registers[SR].reset;
    s->cr = s->part->registers[CR].reset;
    s->optcr = s->part->registers[OPTCR].reset;
    s->key_step = 0;
    s->locked_out = false;
    s->busy_until_ns = 0;
    timer_del(s->busy);
    qemu_set_irq(s->irq, 0);
}

static void flash_if_init(Object *obj)
{
    RigStm32FlashIfState *s = RIG_STM32_FLASH_IF(obj);
    memory_region_init_io(&s->iomem, obj, &flash_if_ops, s, TYPE_RIG_STM32_FLASH_IF, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    sysbus_init_irq(SYS_BUS_DEVICE(obj), &s->irq);
    s->busy = timer_new_ns(QEMU_CLOCK_VIRTUAL, flash_done, s);
}

void rig_stm32_flash_if_over(RigStm32FlashIfState *s, MemoryRegion *rom)
{
    s->rom = rom;
    memset(memory_region_get_ram_ptr(rom), 0xFF, RIG_FLASH_BYTES); /* erased, as the chip comes */
    memory_region_set_enabled(&s->cells, false);
}

/* The machine's first start (after the loader wrote the image into the ROM): the cells take over */
static void flash_if_first_start(void *opaque, bool running, RunState state)
{
    RigStm32FlashIfState *s = opaque;
    if (!running || s->rom == NULL || s->cells.enabled) {
        return;
    }
    memcpy(memory_region_get_ram_ptr(&s->cells), memory_region_get_ram_ptr(s->rom), RIG_FLASH_BYTES);
    memory_region_flush_rom_device(&s->cells, 0, RIG_FLASH_BYTES);
    memory_region_set_enabled(&s->cells, true);
}

/* The cells: a system reset keeps them as the chip's flash keeps its contents */
static void flash_if_realize(DeviceState *dev, Error **errp)
{
    RigStm32FlashIfState *s = RIG_STM32_FLASH_IF(dev);
    Error *err = NULL;
    switch (s->chip) {
    case 405:
        s->part = &flash_f405;
        break;
    case 411:
        s->part = &flash_f411;
        break;
    default:
        error_setg(errp, "rig-stm32f4-flash-if: chip %u is not 405 or 411", s->chip);
        return;
    }
    memory_region_init_rom_device(&s->cells, OBJECT(dev), &flash_cells_ops, s, "rig-stm32f4-flash", RIG_FLASH_BYTES,
                                  &err);
    if (err != NULL) {
        error_propagate(errp, err);
        return;
    }
    memset(memory_region_get_ram_ptr(&s->cells), 0xFF, RIG_FLASH_BYTES);
    sysbus_init_mmio(SYS_BUS_DEVICE(dev), &s->cells);
    qemu_add_vm_change_state_handler(flash_if_first_start, s);
}

static Property flash_if_properties[] = {
    DEFINE_PROP_UINT32("chip", RigStm32FlashIfState, chip, 405),
    DEFINE_PROP_END_OF_LIST(),
};

static void flash_if_class_init(ObjectClass *klass, void *data)
{
    device_class_set_props(DEVICE_CLASS(klass), flash_if_properties);
    DEVICE_CLASS(klass)->reset = flash_if_reset;
    DEVICE_CLASS(klass)->realize = flash_if_realize;
}

static const TypeInfo flash_if_info = {
    .name = TYPE_RIG_STM32_FLASH_IF,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32FlashIfState),
    .instance_init = flash_if_init,
    .class_init = flash_if_class_init,
};

static void flash_if_register_types(void) { type_register_static(&flash_if_info); }

type_init(flash_if_register_types)
