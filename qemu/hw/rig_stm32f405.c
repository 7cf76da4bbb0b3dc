/*
 * rig-stm32f405: QEMU's STM32F405 SoC (Cortex-M4F with NVIC and SysTick, its USARTs, TIM2-5, ADCs, SPIs,
 * SYSCFG and EXTI) with the rig's models mapped over the regions that SoC leaves unimplemented: RCC,
 * PWR, the FLASH interface, GPIO A..I (RM0090), and the core's DWT cycle counter. The RCC's AHB clock
 * drives the core, SysTick and DWT, so the machine starts at 16 MHz (HSI) as the chip does, and runs at
 * what the firmware sets up (168 MHz from an 8 MHz crystal: -global rig-stm32f4-rcc.hse-hz=N for another).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "exec/address-spaces.h"
#include "hw/arm/boot.h"
#include "hw/arm/stm32f405_soc.h"
#include "hw/boards.h"
#include "hw/qdev-clock.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "rig_stm32f4.h"

/* RM0090 table 10 (register boundary addresses) */
#define RCC_BASE 0x40023800
#define RCC_AHB1RSTR 0x10
#define RCC_APB1RSTR 0x20
#define APB1RSTR_PWRRST 28
#define PWR_BASE 0x40007000
#define FLASH_IF_BASE 0x40023C00
#define GPIOA_BASE 0x40020000
#define GPIO_STRIDE 0x400
#define GPIO_PORTS 9
/* ARMv7-M: the DWT in the private peripheral bus */
#define DWT_BASE 0xE0001000

static SysBusDevice *map_device(const char *type, hwaddr base, RigStm32RccState *rcc, int port)
{
    DeviceState *dev = qdev_new(type);
    if (rcc != NULL) {
        object_property_set_link(OBJECT(dev), "rcc", OBJECT(rcc), &error_fatal);
    }
    if (port >= 0) {
        qdev_prop_set_uint8(dev, "port", port);
    }
    sysbus_realize_and_unref(SYS_BUS_DEVICE(dev), &error_fatal);
    /* over the SoC's unimplemented-device placeholders (priority -1000) */
    sysbus_mmio_map(SYS_BUS_DEVICE(dev), 0, base);
    return SYS_BUS_DEVICE(dev);
}

static void rig_stm32f405_init(MachineState *machine)
{
    DeviceState *rcc = qdev_new(TYPE_RIG_STM32_RCC);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(rcc), &error_fatal);
    sysbus_mmio_map(SYS_BUS_DEVICE(rcc), 0, RCC_BASE);
    Clock *hclk = qdev_get_clock_out(rcc, "hclk");

    DeviceState *soc = qdev_new(TYPE_STM32F405_SOC);
    qdev_prop_set_string(soc, "cpu-type", ARM_CPU_TYPE_NAME("cortex-m4"));
    qdev_connect_clock_in(soc, "sysclk", hclk);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(soc), &error_fatal);

    RigStm32RccState *r = RIG_STM32_RCC(rcc);
    rig_stm32_rcc_add_reset(r, RCC_APB1RSTR, APB1RSTR_PWRRST, DEVICE(map_device(TYPE_RIG_STM32_PWR, PWR_BASE, r, -1)));
    map_device(TYPE_RIG_STM32_FLASH_IF, FLASH_IF_BASE, NULL, -1);
    for (int port = 0; port < GPIO_PORTS; port++) {
        SysBusDevice *gpio = map_device(TYPE_RIG_STM32_GPIO, GPIOA_BASE + port * GPIO_STRIDE, r, port);
        rig_stm32_rcc_add_reset(r, RCC_AHB1RSTR, port, DEVICE(gpio)); /* GPIOxRST: bit x */
    }

    DeviceState *dwt = qdev_new(TYPE_RIG_DWT);
    qdev_connect_clock_in(dwt, "hclk", hclk);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(dwt), &error_fatal);
    memory_region_add_subregion_overlap(&STM32F405_SOC(soc)->armv7m.container, DWT_BASE,
                                        sysbus_mmio_get_region(SYS_BUS_DEVICE(dwt), 0), 0);

    armv7m_load_kernel(ARM_CPU(first_cpu), machine->kernel_filename, 0, FLASH_SIZE);
}

static void rig_stm32f405_machine_init(MachineClass *mc)
{
    mc->desc = "STM32F405 with the rig's RCC, PWR, FLASH, GPIO and DWT models (Cortex-M4)";
    mc->init = rig_stm32f405_init;
}

DEFINE_MACHINE("rig-stm32f405", rig_stm32f405_machine_init)
