/*
 * rig-stm32f405: QEMU's STM32F405 SoC (Cortex-M4F, NVIC, SysTick, USARTs, TIM2-5) with the rig's
 * models of what a flight controller's start-up needs from RM0090 mapped over its unimplemented regions.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/arm/boot.h"
#include "hw/arm/stm32f405_soc.h"
#include "hw/boards.h"
#include "hw/qdev-clock.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"

/* RM0090 6.2.2: after reset the system clock is the 16 MHz internal RC oscillator (HSI) */
#define HSI_HZ 16000000ULL

static void rig_stm32f405_init(MachineState *machine)
{
    Clock *sysclk = clock_new(OBJECT(machine), "SYSCLK");
    clock_set_hz(sysclk, HSI_HZ);

    DeviceState *soc = qdev_new(TYPE_STM32F405_SOC);
    qdev_prop_set_string(soc, "cpu-type", ARM_CPU_TYPE_NAME("cortex-m4"));
    qdev_connect_clock_in(soc, "sysclk", sysclk);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(soc), &error_fatal);

    armv7m_load_kernel(ARM_CPU(first_cpu), machine->kernel_filename, 0, FLASH_SIZE);
}

static void rig_stm32f405_machine_init(MachineClass *mc)
{
    mc->desc = "STM32F405 with the rig's RCC, PWR, FLASH, GPIO and DWT models (Cortex-M4)";
    mc->init = rig_stm32f405_init;
}

DEFINE_MACHINE("rig-stm32f405", rig_stm32f405_machine_init)
