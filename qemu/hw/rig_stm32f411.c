/*
 * rig-stm32f411: the STM32F411xC/E (RM0383, the F411's reference manual; DS10314, its datasheet) as the
 * rig-stm32f405 machine's construction (rig_stm32f405.c) from this chip's table: the same models, with
 * only what the F411 has. Its timers are TIM1-TIM5 and TIM9-TIM11 (the pins of DS10314's table 9, which
 * are DS8626's for these timers), its GPIO ports A-E and H (PH0/PH1), its USARTs 1, 2 and 6, 512 KB of
 * flash and 128 KB of SRAM, and no CCM RAM. What QEMU's F405 SoC maps and the F411 lacks answers with a
 * bus error (RM0383 section 2.3, the memory map: those ranges are "Reserved"). The RCC has the F411's
 * registers (RM0383 section 6.3, its register map). The board's crystal is -global rig-stm32f4-rcc.hse-hz (the Black Pill's
 * 25 MHz).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/boards.h"
#include "rig_stm32f4.h"

#define KB 1024

/* RM0383 section 2.3 (the memory map, register boundary addresses) against RM0090's: what the F405 has
 * at these addresses and the F411 has not */
static const RigStm32Region f411_absent[] = {
    { 0x00080000, 512 * KB, "flash beyond the F411's 512 KB (its alias at 0)" },
    { 0x08080000, 512 * KB, "flash beyond the F411's 512 KB" },
    { 0x10000000, 64 * KB, "CCM data RAM (the F411 has none)" },
    { 0x20020000, 64 * KB, "SRAM beyond the F411's 128 KB" },
    { 0x40001000, KB, "TIM6 (not on the F411)" },
    { 0x40001400, KB, "TIM7 (not on the F411)" },
    { 0x40001800, KB, "TIM12 (not on the F411)" },
    { 0x40001C00, KB, "TIM13 (not on the F411)" },
    { 0x40002000, KB, "TIM14 (not on the F411)" },
    { 0x40004800, KB, "USART3 (not on the F411)" },
    { 0x40004C00, KB, "UART4 (not on the F411)" },
    { 0x40005000, KB, "UART5 (not on the F411)" },
    { 0x40010400, KB, "TIM8 (not on the F411)" },
    { 0x40021400, KB, "GPIOF (not on the F411)" },
    { 0x40021800, KB, "GPIOG (not on the F411)" },
    { 0x40022000, KB, "GPIOI (not on the F411)" },
    /* and what QEMU's SoC places as the F405's or beyond it (its UART7/UART8 and SPI6) */
    { 0x40006400, KB, "CAN1 (not on the F411)" },
    { 0x40006800, KB, "CAN2 (not on the F411)" },
    { 0x40007400, KB, "DAC (not on the F411)" },
    { 0x40007800, KB, "UART7 (not on the F411)" },
    { 0x40007C00, KB, "UART8 (not on the F411)" },
    { 0x40015400, KB, "SPI6 (not on the F411)" },
    { 0x40024000, 4 * KB, "backup SRAM (not on the F411)" },
    { 0x40028000, 5 * KB, "Ethernet MAC (not on the F411)" },
    { 0x40040000, 256 * KB, "USB OTG HS (not on the F411)" },
    { 0x50050000, KB, "DCMI (not on the F411)" },
    { 0x50060800, KB, "RNG (not on the F411)" },
};

static const RigStm32Chip f411 = {
    .name = "rig-stm32f411",
    .part = 411,
    .flash_size = 512 * KB,
    .timers = 0x0E3E,                                                         /* TIM1..TIM5, TIM9..TIM11 */
    .usarts = 0x46,                                                           /* USART1, USART2, USART6 */
    .adcs = 1,                                                                /* ADC1 (RM0383 section 11) */
    .port_pins = { 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0, 0, 0x0003, 0 }, /* A..E, PH0/PH1 */
    .absent = f411_absent,
    .n_absent = ARRAY_SIZE(f411_absent),
};

static void rig_stm32f411_init(MachineState *machine) { rig_stm32f4_machine_init(machine, &f411); }

static void rig_stm32f411_machine_init(MachineClass *mc)
{
    rig_stm32f4_machine_class_init(
        mc, "STM32F411 with the rig's RCC, PWR, FLASH, GPIO, DMA, I2C, timer and DWT models and a GY-86 on I2C1");
    mc->init = rig_stm32f411_init;
}

DEFINE_MACHINE("rig-stm32f411", rig_stm32f411_machine_init)
