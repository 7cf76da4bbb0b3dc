/*
 * The rig's STM32F4 device models (RM0090, the STM32F405/415/407/417 reference manual): RCC and PWR,
 * the FLASH interface, GPIO ports and the Cortex-M4's DWT cycle counter.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#ifndef RIG_STM32F4_H
#define RIG_STM32F4_H

#include "hw/clock.h"
#include "hw/sysbus.h"
#include "qom/object.h"

/*
 * One register of a block, as the reference manual's register map gives it: its offset, its reset
 * value and the bits software can write (the rest read as the hardware sets them).
 */
typedef struct RigRegister {
    uint16_t offset;
    const char *name;
    uint32_t reset;
    uint32_t writable;
} RigRegister;

/* The index of the register at @offset in @table, or -1 when the block has none there */
int rig_register_index(const RigRegister *table, int count, hwaddr offset);

/* RCC (RM0090 section 7.3) */
#define TYPE_RIG_STM32_RCC "rig-stm32f4-rcc"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32RccState, RIG_STM32_RCC)
#define RIG_RCC_REGISTERS 23
#define RIG_RCC_RESETS 32

struct RigStm32RccState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t regs[RIG_RCC_REGISTERS];
    uint32_t hse_hz; /* the board's crystal (property "hse-hz") */
    Clock *hclk;     /* the AHB clock: the core, SysTick, DWT */
    /* the peripherals the reset registers (AHB1RSTR ... APB2RSTR) reset: register, bit, device */
    struct {
        hwaddr rstr_offset;
        unsigned bit;
        DeviceState *dev;
    } resets[RIG_RCC_RESETS];
    unsigned n_resets;
};

/* Whether the clock of bit @bit of the enable register at @enr_offset (AHB1ENR, APB1ENR, ...) is on */
bool rig_stm32_rcc_enabled(RigStm32RccState *rcc, hwaddr enr_offset, unsigned bit);

/* @dev is reset while bit @bit of the reset register at @rstr_offset is set (RM0090 7.3.5-7.3.9) */
void rig_stm32_rcc_add_reset(RigStm32RccState *rcc, hwaddr rstr_offset, unsigned bit, DeviceState *dev);

/* PWR (RM0090 section 5.4) */
#define TYPE_RIG_STM32_PWR "rig-stm32f4-pwr"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32PwrState, RIG_STM32_PWR)

struct RigStm32PwrState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t cr, csr;
    RigStm32RccState *rcc;
};

/* The FLASH interface (RM0090 section 3.9) */
#define TYPE_RIG_STM32_FLASH_IF "rig-stm32f4-flash-if"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32FlashIfState, RIG_STM32_FLASH_IF)

struct RigStm32FlashIfState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t acr, sr, cr, optcr;
    uint8_t key_step; /* 1 after KEY1 was written to KEYR */
    bool locked_out;  /* a wrong key: CR stays locked until reset */
};

/* GPIO ports A..I (RM0090 section 8.4) */
#define TYPE_RIG_STM32_GPIO "rig-stm32f4-gpio"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32GpioState, RIG_STM32_GPIO)
#define RIG_GPIO_PINS 16

struct RigStm32GpioState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint8_t port; /* 0 for A ... 8 for I (property "port") */
    RigStm32RccState *rcc;
    uint32_t moder, otyper, ospeedr, pupdr, odr, afr[2];
    uint32_t lckr;      /* LCK[15:0] and LCKK once the lock sequence has completed */
    uint8_t lock_step;  /* how far the lock key sequence has come */
    uint32_t lock_try;  /* the LCK bits written in its first step */
    uint16_t ext_level; /* what outside drivers put on the pins (qdev GPIO inputs) */
    uint16_t ext_driven;
    uint16_t pins; /* the levels last sent out */
    qemu_irq out[RIG_GPIO_PINS];
};

/* The pin levels a port shows on its IDR */
uint16_t rig_stm32_gpio_levels(RigStm32GpioState *s);

/* DWT (ARMv7-M ARM C1.8): CYCCNT counts HCLK cycles in virtual time */
#define TYPE_RIG_DWT "rig-dwt"
OBJECT_DECLARE_SIMPLE_TYPE(RigDwtState, RIG_DWT)

struct RigDwtState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    Clock *hclk;
    uint32_t ctrl;
    uint32_t cyccnt_base; /* CYCCNT when counting last (re)started */
    int64_t base_ns;      /* the virtual time then */
};

#endif
