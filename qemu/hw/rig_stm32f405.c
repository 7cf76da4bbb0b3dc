/*
 * rig-stm32f405: QEMU's STM32F405 SoC (Cortex-M4F with NVIC and SysTick, TIM2-5, ADCs, SPIs,
 * SYSCFG and EXTI) with the rig's models mapped over the regions that SoC leaves unimplemented: RCC,
 * PWR, the FLASH interface (its flash cells over the SoC's ROM), the IWDG and WWDG, GPIO A..I, SYSCFG and EXTI (over the SoC's), DMA1 and DMA2, I2C1 (RM0090) with the GY-86 board (the rig's chip core) on its
 * bus, the timers TIM1-TIM14 (over QEMU's TIM2-TIM5, which only count) with their channels on the pins
 * of the datasheet's alternate function table, USART1-USART6 (over QEMU's, which get no chardev: ours send
 * into the chardevs named rig-usart1..rig-usart6), ADC1-ADC3 (over QEMU's), and the core's DWT cycle counter. The RCC's AHB clock
 * drives the core, SysTick and DWT, so the machine starts at 16 MHz (HSI) as the chip does, and runs at
 * what the firmware sets up (168 MHz from an 8 MHz crystal: -global rig-stm32f4-rcc.hse-hz=N for another).
 * The machine's "wires" property joins pins as a board's traces or a test's jumper wires do: -M
 * rig-stm32f405,wires=PD12-PA0 drives PA0 from outside with PD12's level (a PWM output into an input
 * capture); several pairs go joined by "+".
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "chardev/char.h"
#include "exec/address-spaces.h"
#include "hw/arm/boot.h"
#include "hw/arm/stm32f405_soc.h"
#include "hw/boards.h"
#include "hw/or-irq.h"
#include "hw/qdev-clock.h"
#include "hw/qdev-properties-system.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/error-report.h"
#include "qemu/log.h"
#include "rig_stm32f4.h"

/* RM0090 table 10 (register boundary addresses) */
#define RCC_BASE 0x40023800
#define RCC_AHB1RSTR 0x10
#define RCC_APB1RSTR 0x20
#define APB1RSTR_PWRRST 28
#define PWR_BASE 0x40007000
#define FLASH_IF_BASE 0x40023C00
#define FLASH_BASE 0x08000000 /* RM0090 2.3: the main flash, also at 0 when booting from it */
#define IRQ_FLASH 4           /* RM0090 table 61 */
#define IWDG_BASE 0x40003000
#define WWDG_BASE 0x40002C00
#define APB1_WWDG 11 /* RCC_APB1ENR.WWDGEN and RCC_APB1RSTR.WWDGRST */
#define IRQ_WWDG 0
#define GPIOA_BASE 0x40020000
#define GPIO_STRIDE 0x400
#define I2C1_BASE 0x40005400
#define APB1_I2C1 21   /* RCC_APB1ENR.I2C1EN and RCC_APB1RSTR.I2C1RST */
#define IRQ_I2C1_EV 31 /* RM0090 table 61 (vector table) */
#define IRQ_I2C1_ER 32
#define RCC_APB2RSTR 0x24
#define SYSCFG_BASE 0x40013800
#define EXTI_BASE 0x40013C00
#define APB2_SYSCFG 14      /* RCC_APB2RSTR.SYSCFGRST */
#define ADC_BASE 0x40012000 /* ADC1, ADC2, ADC3 a 0x100 apart, the common registers at 0x300 */
#define APB2_ADC 8          /* RCC_APB2RSTR.ADCRST: all of them */
#define IRQ_ADC 18          /* ADC1, ADC2 and ADC3 share it */
/* DMA1 and DMA2 (table 10), their reset bits in AHB1RSTR (7.3.5: DMA1RST 21, DMA2RST 22) and the streams'
 * NVIC lines (table 61) */
static const struct {
    hwaddr base;
    uint8_t reset_bit;
    uint8_t irq[RIG_DMA_STREAMS];
} dma_map[2] = {
    { 0x40026000, 21, { 11, 12, 13, 14, 15, 16, 17, 47 } },
    { 0x40026400, 22, { 56, 57, 58, 59, 60, 68, 69, 70 } },
};
/* the NVIC's inputs (QEMU's STM32F405 SoC has 96) */
#define NVIC_LINES 96

/* The timers: base (RM0090 table 10), APB and their bit in APBxENR and APBxRSTR (7.3.7, 7.3.8, 7.3.11,
 * 7.3.12), NVIC lines (table 61): the
 * advanced timers' BRK, UP, TRG_COM and CC, the others' one global line (-1: none) */
static const struct {
    hwaddr base;
    uint8_t apb, reset_bit;
    int8_t irq[RIG_TIM_IRQS];
} timer_map[15] = {
    [1] = { 0x40010000, 2, 0, { 24, 25, 26, 27 } },   [2] = { 0x40000000, 1, 0, { 28, -1, -1, -1 } },
    [3] = { 0x40000400, 1, 1, { 29, -1, -1, -1 } },   [4] = { 0x40000800, 1, 2, { 30, -1, -1, -1 } },
    [5] = { 0x40000C00, 1, 3, { 50, -1, -1, -1 } },   [6] = { 0x40001000, 1, 4, { 54, -1, -1, -1 } },
    [7] = { 0x40001400, 1, 5, { 55, -1, -1, -1 } },   [8] = { 0x40010400, 2, 1, { 43, 44, 45, 46 } },
    [9] = { 0x40014000, 2, 16, { 24, -1, -1, -1 } },  [10] = { 0x40014400, 2, 17, { 25, -1, -1, -1 } },
    [11] = { 0x40014800, 2, 18, { 26, -1, -1, -1 } }, [12] = { 0x40001800, 1, 6, { 43, -1, -1, -1 } },
    [13] = { 0x40001C00, 1, 7, { 44, -1, -1, -1 } },  [14] = { 0x40002000, 1, 8, { 45, -1, -1, -1 } },
};

/* The USARTs: base (RM0090 table 10), APB and bit in APBxENR/APBxRSTR (7.3.13, 7.3.14), NVIC line (table
 * 61); UART4 and UART5 have no synchronous mode */
static const struct {
    hwaddr base;
    uint8_t apb, rcc_bit, irq;
} usart_map[7] = {
    [1] = { 0x40011000, 2, 4, 37 },  [2] = { 0x40004400, 1, 17, 38 }, [3] = { 0x40004800, 1, 18, 39 },
    [4] = { 0x40004C00, 1, 19, 52 }, [5] = { 0x40005000, 1, 20, 53 }, [6] = { 0x40011400, 2, 5, 71 },
};

/* The timer channels' pins (DS8626, the STM32F405xx datasheet, table 9: alternate function mapping):
 * AF1 TIM1/TIM2, AF2 TIM3/TIM4/TIM5, AF3 TIM8..TIM11, AF9 TIM12..TIM14; the complementary outputs CH1N..
 * CH3N of TIM1/TIM8 (output only) after the channels. ETR and BKIN are not listed (not modelled). */
typedef struct {
    uint8_t timer, channel; /* channel 1..4 */
    char port;
    uint8_t pin;
    bool complementary; /* CHxN */
} TimerPin;
static const TimerPin timer_pins[] = {
    { 1, 1, 'A', 8 },        { 1, 1, 'E', 9 },        { 1, 2, 'A', 9 },        { 1, 2, 'E', 11 },
    { 1, 3, 'A', 10 },       { 1, 3, 'E', 13 },       { 1, 4, 'A', 11 },       { 1, 4, 'E', 14 },
    { 2, 1, 'A', 0 },        { 2, 1, 'A', 5 },        { 2, 1, 'A', 15 },       { 2, 2, 'A', 1 },
    { 2, 2, 'B', 3 },        { 2, 3, 'A', 2 },        { 2, 3, 'B', 10 },       { 2, 4, 'A', 3 },
    { 2, 4, 'B', 11 },       { 3, 1, 'A', 6 },        { 3, 1, 'B', 4 },        { 3, 1, 'C', 6 },
    { 3, 2, 'A', 7 },        { 3, 2, 'B', 5 },        { 3, 2, 'C', 7 },        { 3, 3, 'B', 0 },
    { 3, 3, 'C', 8 },        { 3, 4, 'B', 1 },        { 3, 4, 'C', 9 },        { 4, 1, 'B', 6 },
    { 4, 1, 'D', 12 },       { 4, 2, 'B', 7 },        { 4, 2, 'D', 13 },       { 4, 3, 'B', 8 },
    { 4, 3, 'D', 14 },       { 4, 4, 'B', 9 },        { 4, 4, 'D', 15 },       { 5, 1, 'A', 0 },
    { 5, 1, 'H', 10 },       { 5, 2, 'A', 1 },        { 5, 2, 'H', 11 },       { 5, 3, 'A', 2 },
    { 5, 3, 'H', 12 },       { 5, 4, 'A', 3 },        { 5, 4, 'I', 0 },        { 8, 1, 'C', 6 },
    { 8, 1, 'I', 5 },        { 8, 2, 'C', 7 },        { 8, 2, 'I', 6 },        { 8, 3, 'C', 8 },
    { 8, 3, 'I', 7 },        { 8, 4, 'C', 9 },        { 8, 4, 'I', 2 },        { 9, 1, 'A', 2 },
    { 9, 1, 'E', 5 },        { 9, 2, 'A', 3 },        { 9, 2, 'E', 6 },        { 10, 1, 'B', 8 },
    { 10, 1, 'F', 6 },       { 11, 1, 'B', 9 },       { 11, 1, 'F', 7 },       { 12, 1, 'B', 14 },
    { 12, 1, 'H', 6 },       { 12, 2, 'B', 15 },      { 12, 2, 'H', 9 },       { 13, 1, 'A', 6 },
    { 13, 1, 'F', 8 },       { 14, 1, 'A', 7 },       { 14, 1, 'F', 9 },       { 1, 1, 'A', 7, true },
    { 1, 1, 'B', 13, true }, { 1, 1, 'E', 8, true },  { 1, 2, 'B', 0, true },  { 1, 2, 'B', 14, true },
    { 1, 2, 'E', 10, true }, { 1, 3, 'B', 1, true },  { 1, 3, 'B', 15, true }, { 1, 3, 'E', 12, true },
    { 8, 1, 'A', 5, true },  { 8, 1, 'A', 7, true },  { 8, 1, 'H', 13, true }, { 8, 2, 'B', 0, true },
    { 8, 2, 'B', 14, true }, { 8, 2, 'H', 14, true }, { 8, 3, 'B', 1, true },  { 8, 3, 'B', 15, true },
    { 8, 3, 'H', 15, true },
};

static unsigned timer_af(unsigned timer)
{
    switch (timer) {
    case 1:
    case 2:
        return 1;
    case 3:
    case 4:
    case 5:
        return 2;
    case 12:
    case 13:
    case 14:
        return 9;
    default: /* 8..11 */
        return 3;
    }
}

/* The machine's "wires" property: pairs of pins joined, "PD12-PA0+PB0-PC1" */
static char *wires_spec;

/* RM0090 table 3: the CCM data RAM; QEMU's SoC has 192 KB of SRAM from 0x20000000 instead */
#define CCM_BASE 0x10000000
#define SRAM_SIZE_F4 (128 * 1024)

/* the chardev id that links the machine to the rig's session */
#define LINK_CHARDEV "rig-link"
/* ARMv7-M: the DWT in the private peripheral bus */
#define DWT_BASE 0xE0001000
/* the board's own address on QEMU's bus (it answers every address the chip core acknowledges) */
#define CHIP_ADDR_MPU_SLAVE 0x68

/* @type at @base, linked to @rcc (unless NULL), its "port" set (unless -1) and its "chip" (unless 0: a
 * model with one table for the family) */
static SysBusDevice *map_device(const char *type, hwaddr base, RigStm32RccState *rcc, int port, uint32_t part)
{
    DeviceState *dev = qdev_new(type);
    if (part != 0) {
        qdev_prop_set_uint32(dev, "chip", part);
    }
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

/* The FLASH interface's cells over the SoC's flash ROM, at 0x08000000 and at 0, in the core's own address
 * space (rig_stm32_flash_if.c: they take the ROM's place when the machine first starts) */
static void map_flash(SysBusDevice *soc, SysBusDevice *flash_if, uint32_t flash_size)
{
    MemoryRegion *container = &STM32F405_SOC(soc)->armv7m.container, *cells = sysbus_mmio_get_region(flash_if, 1);
    /* as much of the cells as the chip has (the F411's 512 KB: what lies above is absent, map_absent) */
    MemoryRegion *main = g_new0(MemoryRegion, 1), *alias = g_new0(MemoryRegion, 1);
    memory_region_init_alias(main, OBJECT(flash_if), "rig-stm32f4-flash", cells, 0, MIN(flash_size, RIG_FLASH_BYTES));
    memory_region_init_alias(alias, OBJECT(flash_if), "rig-stm32f4-flash-alias", cells, 0,
                             MIN(flash_size, RIG_FLASH_BYTES));
    memory_region_add_subregion_overlap(container, FLASH_BASE, main, 1);
    memory_region_add_subregion_overlap(container, 0, alias, 1);
    sysbus_connect_irq(flash_if, 0, qdev_get_gpio_in(DEVICE(&STM32F405_SOC(soc)->armv7m), IRQ_FLASH));
    rig_stm32_flash_if_over(RIG_STM32_FLASH_IF(flash_if), &STM32F405_SOC(soc)->flash);
}

/* TIM1..TIM14 over the SoC's placeholders and its TIM2-TIM5, their interrupts (an OR gate where two
 * timers share a line), reset bits, clocks and pins */
static void map_timers(const RigStm32Chip *chip, RigStm32RccState *rcc, DeviceState *nvic, DeviceState **gpio_ports,
                       DeviceState **dma)
{
    DeviceState *tim[15] = { NULL };
    unsigned users[NVIC_LINES] = { 0 }, wired[NVIC_LINES] = { 0 };
    DeviceState *gate[NVIC_LINES] = { NULL };
    for (unsigned t = 1; t <= 14; t++) {
        if (!(chip->timers >> t & 1u)) {
            continue;
        }
        for (unsigned k = 0; k < RIG_TIM_IRQS; k++) {
            if (timer_map[t].irq[k] >= 0) {
                users[timer_map[t].irq[k]]++;
            }
        }
    }
    for (unsigned t = 1; t <= 14; t++) {
        if (!(chip->timers >> t & 1u)) {
            continue;
        }
        DeviceState *dev = qdev_new(TYPE_RIG_STM32_TIMER);
        g_autofree char *name = g_strdup_printf("tim%u", t);
        object_property_add_child(qdev_get_machine(), name, OBJECT(dev)); /* /machine/timN */
        qdev_prop_set_uint8(dev, "index", t);
        qdev_prop_set_uint8(dev, "apb", timer_map[t].apb);
        qdev_prop_set_uint8(dev, "rcc-bit", timer_map[t].reset_bit);
        object_property_set_link(OBJECT(dev), "rcc", OBJECT(rcc), &error_fatal);
        qdev_connect_clock_in(dev, "clk",
                              qdev_get_clock_out(DEVICE(rcc), timer_map[t].apb == 1 ? "apb1-tim" : "apb2-tim"));
        sysbus_realize_and_unref(SYS_BUS_DEVICE(dev), &error_fatal);
        sysbus_mmio_map_overlap(SYS_BUS_DEVICE(dev), 0, timer_map[t].base, 1);
        rig_stm32_rcc_add_reset(rcc, timer_map[t].apb == 1 ? RCC_APB1RSTR : RCC_APB2RSTR, timer_map[t].reset_bit, dev);
        for (unsigned k = 0; k < RIG_TIM_IRQS; k++) {
            int line = timer_map[t].irq[k];
            if (line < 0) {
                continue;
            }
            if (users[line] == 1) {
                sysbus_connect_irq(SYS_BUS_DEVICE(dev), k, qdev_get_gpio_in(nvic, line));
                continue;
            }
            if (gate[line] == NULL) {
                gate[line] = qdev_new(TYPE_OR_IRQ);
                qdev_prop_set_uint16(gate[line], "num-lines", users[line]);
                qdev_realize_and_unref(gate[line], NULL, &error_fatal);
                qdev_connect_gpio_out(gate[line], 0, qdev_get_gpio_in(nvic, line));
            }
            sysbus_connect_irq(SYS_BUS_DEVICE(dev), k, qdev_get_gpio_in(gate[line], wired[line]++));
        }
        /* the DMA requests: TIM1 and TIM8 on DMA2, the others on DMA1 (the request mapping is the DMA's) */
        for (unsigned k = 0; k < RIG_DMA_TIM_REQS; k++) {
            qdev_connect_gpio_out_named(dev, "dma", k,
                                        qdev_get_gpio_in_named(dma[t == 1 || t == 8], "request", RIG_DMA_TIMER(t, k)));
        }
        tim[t] = dev;
    }
    unsigned slot[15][RIG_TIM_OUTPUTS] = { { 0 } };
    for (unsigned i = 0; i < ARRAY_SIZE(timer_pins); i++) {
        const TimerPin *p = &timer_pins[i];
        /* the family's table, less what the chip lacks: the timer, or the pin (DS10314 table 9 is DS8626's
         * for the timers and pins the F411 has) */
        if (tim[p->timer] == NULL || !(chip->port_pins[p->port - 'A'] >> p->pin & 1u)) {
            continue;
        }
        DeviceState *port = gpio_ports[p->port - 'A'];
        unsigned line = RIG_GPIO_AF_LINE(p->pin, timer_af(p->timer)), ch = p->channel - 1;
        unsigned output = p->complementary ? RIG_TIM_CHANNELS + ch : ch;
        assert(slot[p->timer][output] < RIG_TIM_PINS_PER_CHANNEL);
        qdev_connect_gpio_out_named(tim[p->timer], "channel-out",
                                    output * RIG_TIM_PINS_PER_CHANNEL + slot[p->timer][output]++,
                                    qdev_get_gpio_in_named(port, "af-drive", line));
        if (!p->complementary) {
            qdev_connect_gpio_out_named(port, "af-input", line,
                                        qdev_get_gpio_in_named(tim[p->timer], "channel-in", ch));
        }
    }
}

/* SYSCFG and EXTI over the SoC's (which take port A's pins only): every pin into SYSCFG's multiplexer, its
 * lines into EXTI, EXTI's requests to the NVIC */
static void map_exti(RigStm32RccState *rcc, DeviceState *nvic, DeviceState **gpio_ports)
{
    DeviceState *syscfg = qdev_new(TYPE_RIG_STM32_SYSCFG);
    object_property_set_link(OBJECT(syscfg), "rcc", OBJECT(rcc), &error_fatal);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(syscfg), &error_fatal);
    sysbus_mmio_map_overlap(SYS_BUS_DEVICE(syscfg), 0, SYSCFG_BASE, 1);
    rig_stm32_rcc_add_reset(rcc, RCC_APB2RSTR, APB2_SYSCFG, syscfg);
    DeviceState *exti = qdev_new(TYPE_RIG_STM32_EXTI);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(exti), &error_fatal);
    sysbus_mmio_map_overlap(SYS_BUS_DEVICE(exti), 0, EXTI_BASE, 1);
    for (unsigned k = 0; k < RIG_EXTI_IRQS; k++) {
        sysbus_connect_irq(SYS_BUS_DEVICE(exti), k, qdev_get_gpio_in(nvic, rig_exti_nvic[k]));
    }
    for (unsigned line = 0; line < RIG_GPIO_PINS; line++) {
        qdev_connect_gpio_out_named(syscfg, "line", line, qdev_get_gpio_in_named(exti, "line", line));
    }
    for (unsigned port = 0; port < RIG_GPIO_PORTS; port++) {
        for (unsigned pin = 0; gpio_ports[port] != NULL && pin < RIG_GPIO_PINS; pin++) {
            qdev_connect_gpio_out_named(gpio_ports[port], "level", pin,
                                        qdev_get_gpio_in_named(syscfg, "pin", port * RIG_GPIO_PINS + pin));
        }
    }
}

/* USART1..USART6 over QEMU's (which keep no chardev: the engine names its chardevs rig-usartN, and the
 * machine gives them to these), as /machine/usartN for the link */
static void map_usarts(const RigStm32Chip *chip, RigStm32RccState *rcc, DeviceState *nvic, DeviceState **dma)
{
    for (unsigned n = 1; n <= 6; n++) {
        if (!(chip->usarts >> n & 1u)) {
            continue;
        }
        DeviceState *dev = qdev_new(TYPE_RIG_STM32_USART);
        g_autofree char *name = g_strdup_printf("usart%u", n);
        g_autofree char *chardev = g_strdup_printf("rig-usart%u", n);
        object_property_add_child(qdev_get_machine(), name, OBJECT(dev));
        qdev_prop_set_uint8(dev, "apb", usart_map[n].apb);
        qdev_prop_set_uint8(dev, "rcc-bit", usart_map[n].rcc_bit);
        qdev_prop_set_bit(dev, "uart", n == 4 || n == 5);
        qdev_prop_set_uint8(dev, "index", n);
        object_property_set_link(OBJECT(dev), "rcc", OBJECT(rcc), &error_fatal);
        /* the DMA requests: USART1 and USART6 on DMA2, the others on DMA1 (the request mapping is the DMA's) */
        DeviceState *controller = dma[n == 1 || n == 6];
        object_property_set_link(OBJECT(dev), "dma", OBJECT(controller), &error_fatal);
        Chardev *chr = qemu_chr_find(chardev);
        if (chr != NULL && chr->be != NULL) {
            error_report("%s: chardev %s is taken (by a -serial?): the machine's USART%u sends to it", chip->name,
                         chardev, n);
            exit(1);
        }
        if (chr != NULL) {
            qdev_prop_set_chr(dev, "chardev", chr);
        }
        sysbus_realize_and_unref(SYS_BUS_DEVICE(dev), &error_fatal);
        sysbus_mmio_map_overlap(SYS_BUS_DEVICE(dev), 0, usart_map[n].base, 1);
        sysbus_connect_irq(SYS_BUS_DEVICE(dev), 0, qdev_get_gpio_in(nvic, usart_map[n].irq));
        qdev_connect_gpio_out_named(dev, "dma-rx", 0,
                                    qdev_get_gpio_in_named(controller, "request", RIG_DMA_USART_RX(n)));
        qdev_connect_gpio_out_named(dev, "dma-tx", 0,
                                    qdev_get_gpio_in_named(controller, "request", RIG_DMA_USART_TX(n)));
        rig_stm32_rcc_add_reset(rcc, usart_map[n].apb == 1 ? RCC_APB1RSTR : RCC_APB2RSTR, usart_map[n].rcc_bit, dev);
    }
}

/* The ADCs over QEMU's (which convert nothing and raise neither interrupt nor DMA request), as
 * /machine/adc for the link; QEMU's SoC places three more past the common registers, where both reference
 * manuals' memory maps have nothing (0x40012400-0x40012BFF): a bus error there */
static const RigStm32Region adc_absent = { 0x40012400, 0x800, "reserved (after the ADCs)" };

static void map_adcs(const RigStm32Chip *chip, RigStm32RccState *rcc, DeviceState *nvic, DeviceState *dma2)
{
    DeviceState *dev = qdev_new(TYPE_RIG_STM32_ADC);
    object_property_add_child(qdev_get_machine(), "adc", OBJECT(dev));
    qdev_prop_set_uint8(dev, "count", chip->adcs);
    qdev_prop_set_uint32(dev, "chip", chip->part);
    object_property_set_link(OBJECT(dev), "rcc", OBJECT(rcc), &error_fatal);
    object_property_set_link(OBJECT(dev), "dma", OBJECT(dma2), &error_fatal);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(dev), &error_fatal);
    sysbus_mmio_map_overlap(SYS_BUS_DEVICE(dev), 0, ADC_BASE, 1);
    sysbus_connect_irq(SYS_BUS_DEVICE(dev), 0, qdev_get_gpio_in(nvic, IRQ_ADC));
    for (unsigned n = 1; n <= chip->adcs; n++) {
        qdev_connect_gpio_out_named(dev, "dma", n - 1, qdev_get_gpio_in_named(dma2, "request", RIG_DMA_ADC(n)));
    }
    rig_stm32_rcc_add_reset(rcc, RCC_APB2RSTR, APB2_ADC, dev);
}

/* "PD12" as a port and pin the chip has, or false */
static bool parse_pin(const RigStm32Chip *chip, const char *text, unsigned *port, unsigned *pin)
{
    char *end;
    if (text[0] != 'P' || text[1] < 'A' || text[1] >= 'A' + RIG_GPIO_PORTS) {
        return false;
    }
    unsigned long n = strtoul(text + 2, &end, 10);
    *port = text[1] - 'A';
    *pin = n;
    return end != text + 2 && *end == '\0' && n < RIG_GPIO_PINS && (chip->port_pins[*port] >> n & 1u);
}

/* The "wires" pairs: the first pin's level drives the second from outside */
static void wire_pins(const RigStm32Chip *chip, DeviceState **gpio_ports)
{
    if (wires_spec == NULL || wires_spec[0] == '\0') {
        return;
    }
    g_auto(GStrv) pairs = g_strsplit(wires_spec, "+", -1);
    for (char **pair = pairs; *pair != NULL; pair++) {
        g_auto(GStrv) ends = g_strsplit(*pair, "-", -1);
        unsigned from_port, from_pin, to_port, to_pin;
        if (g_strv_length(ends) != 2 || !parse_pin(chip, ends[0], &from_port, &from_pin) ||
            !parse_pin(chip, ends[1], &to_port, &to_pin)) {
            error_report("%s: wires: '%s' is not a pair of pins like PD12-PA0 that the chip has", chip->name, *pair);
            exit(1);
        }
        if (qdev_get_gpio_out_connector(gpio_ports[from_port], NULL, from_pin) != NULL) {
            error_report("%s: wires: %s already drives something (PB6-PB9 may carry I2C1)", chip->name, ends[0]);
            exit(1);
        }
        qdev_connect_gpio_out(gpio_ports[from_port], from_pin, qdev_get_gpio_in(gpio_ports[to_port], to_pin));
    }
}

/* An access where the chip has nothing ("Reserved" in its reference manual's memory map): a bus error,
 * as the bus matrix answers an address none of its slaves decodes (a precise BusFault, or a HardFault
 * without BusFault enabled), and a guest_errors log */
static MemTxResult absent_read(void *opaque, hwaddr offset, uint64_t *data, unsigned size, MemTxAttrs attrs)
{
    const RigStm32Region *r = opaque;
    qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4: read of 0x%" HWADDR_PRIx ": %s\n", r->base + offset, r->what);
    *data = 0;
    return MEMTX_ERROR;
}

static MemTxResult absent_write(void *opaque, hwaddr offset, uint64_t data, unsigned size, MemTxAttrs attrs)
{
    const RigStm32Region *r = opaque;
    qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4: write of 0x%" HWADDR_PRIx ": %s\n", r->base + offset, r->what);
    return MEMTX_ERROR;
}

static const MemoryRegionOps absent_ops = {
    .read_with_attrs = absent_read,
    .write_with_attrs = absent_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .valid.min_access_size = 1,
    .valid.max_access_size = 4,
};

/* over the SoC's memories and devices (priority 0) and the rig's models (1) */
#define ABSENT_PRIORITY 10

static void map_absent_region(const RigStm32Region *r)
{
    MemoryRegion *mr = g_new0(MemoryRegion, 1);
    memory_region_init_io(mr, NULL, &absent_ops, (void *)r, r->what, r->size);
    memory_region_add_subregion_overlap(get_system_memory(), r->base, mr, ABSENT_PRIORITY);
}

static void map_absent(const RigStm32Chip *chip)
{
    for (unsigned i = 0; i < chip->n_absent; i++) {
        map_absent_region(&chip->absent[i]);
    }
    map_absent_region(&adc_absent);
}

void rig_stm32f4_machine_init(MachineState *machine, const RigStm32Chip *chip)
{
    DeviceState *rcc = qdev_new(TYPE_RIG_STM32_RCC);
    qdev_prop_set_uint32(rcc, "chip", chip->part);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(rcc), &error_fatal);
    sysbus_mmio_map(SYS_BUS_DEVICE(rcc), 0, RCC_BASE);
    Clock *hclk = qdev_get_clock_out(rcc, "hclk");

    DeviceState *soc = qdev_new(TYPE_STM32F405_SOC);
    qdev_prop_set_string(soc, "cpu-type", ARM_CPU_TYPE_NAME("cortex-m4"));
    qdev_connect_clock_in(soc, "sysclk", hclk);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(soc), &error_fatal);

    RigStm32RccState *r = RIG_STM32_RCC(rcc);
    rig_stm32_rcc_add_reset(r, RCC_APB1RSTR, APB1RSTR_PWRRST,
                            DEVICE(map_device(TYPE_RIG_STM32_PWR, PWR_BASE, r, -1, chip->part)));
    map_flash(SYS_BUS_DEVICE(soc), map_device(TYPE_RIG_STM32_FLASH_IF, FLASH_IF_BASE, NULL, -1, chip->part),
              chip->flash_size);
    map_device(TYPE_RIG_STM32_IWDG, IWDG_BASE, r, -1, 0);
    SysBusDevice *wwdg = map_device(TYPE_RIG_STM32_WWDG, WWDG_BASE, r, -1, 0);
    rig_stm32_rcc_add_reset(r, RCC_APB1RSTR, APB1_WWDG, DEVICE(wwdg));
    DeviceState *gpio_ports[RIG_GPIO_PORTS] = { NULL };
    for (int port = 0; port < RIG_GPIO_PORTS; port++) {
        if (chip->port_pins[port] == 0) {
            continue; /* a port the chip lacks: its slot is in chip->absent */
        }
        SysBusDevice *gpio = map_device(TYPE_RIG_STM32_GPIO, GPIOA_BASE + port * GPIO_STRIDE, r, port, chip->part);
        gpio_ports[port] = DEVICE(gpio);
        rig_stm32_rcc_add_reset(r, RCC_AHB1RSTR, port, DEVICE(gpio)); /* GPIOxRST: bit x */
    }

    DeviceState *nvic = DEVICE(&STM32F405_SOC(soc)->armv7m);
    sysbus_connect_irq(wwdg, 0, qdev_get_gpio_in(nvic, IRQ_WWDG));

    DeviceState *dma[2];
    for (unsigned d = 0; d < 2; d++) {
        dma[d] = qdev_new(TYPE_RIG_STM32_DMA);
        qdev_prop_set_uint8(dma[d], "controller", d + 1);
        object_property_set_link(OBJECT(dma[d]), "rcc", OBJECT(r), &error_fatal);
        sysbus_realize_and_unref(SYS_BUS_DEVICE(dma[d]), &error_fatal);
        sysbus_mmio_map(SYS_BUS_DEVICE(dma[d]), 0, dma_map[d].base);
        for (unsigned n = 0; n < RIG_DMA_STREAMS; n++) {
            sysbus_connect_irq(SYS_BUS_DEVICE(dma[d]), n, qdev_get_gpio_in(nvic, dma_map[d].irq[n]));
        }
        rig_stm32_rcc_add_reset(r, RCC_AHB1RSTR, dma_map[d].reset_bit, dma[d]);
    }

    DeviceState *i2c1 = DEVICE(map_device(TYPE_RIG_STM32_I2C, I2C1_BASE, r, -1, 0));
    qdev_connect_gpio_out_named(i2c1, "dma", 0, qdev_get_gpio_in_named(dma[0], "request", RIG_DMA_I2C1_RX));
    qdev_connect_gpio_out_named(i2c1, "dma", 1, qdev_get_gpio_in_named(dma[0], "request", RIG_DMA_I2C1_TX));
    qdev_connect_gpio_out_named(dma[0], "eot1", RIG_DMA_I2C1_RX, qdev_get_gpio_in_named(i2c1, "dma-eot1", 0));
    sysbus_connect_irq(SYS_BUS_DEVICE(i2c1), 0, qdev_get_gpio_in(nvic, IRQ_I2C1_EV));
    sysbus_connect_irq(SYS_BUS_DEVICE(i2c1), 1, qdev_get_gpio_in(nvic, IRQ_I2C1_ER));
    rig_stm32_rcc_add_reset(r, RCC_APB1RSTR, APB1_I2C1, i2c1);
    I2CSlave *gy86 = i2c_slave_new(TYPE_RIG_GY86, CHIP_ADDR_MPU_SLAVE);
    /* a chardev named "rig-link": the rig's session runs the machine in lockstep (rig_link.c) */
    Chardev *link_chr = qemu_chr_find(LINK_CHARDEV);
    if (link_chr != NULL) {
        DeviceState *link = qdev_new(TYPE_RIG_LINK);
        qdev_prop_set_chr(link, "chardev", link_chr);
        sysbus_realize_and_unref(SYS_BUS_DEVICE(link), &error_fatal);
        object_property_set_link(OBJECT(gy86), "link", OBJECT(link), &error_fatal);
        /* the pins the session drives (a PPM sum): from outside, as a receiver's wire does */
        for (unsigned port = 0; port < RIG_GPIO_PORTS; port++) {
            for (unsigned pin = 0; gpio_ports[port] != NULL && pin < RIG_GPIO_PINS; pin++) {
                if (chip->port_pins[port] >> pin & 1u) {
                    qdev_connect_gpio_out_named(link, "pin", port * RIG_GPIO_PINS + pin,
                                                qdev_get_gpio_in(gpio_ports[port], pin));
                }
            }
        }
    }
    i2c_slave_realize_and_unref(gy86, RIG_STM32_I2C(i2c1)->bus, &error_fatal);
    /* PB6/PB7 or PB8/PB9, as the firmware's AFR selects (rig_stm32_i2c_pins.c): the pins' levels reach the
     * controller, and the bus (its pull-ups, a slave holding SDA) drives the pins from outside */
    rig_stm32_route_i2c1(i2c1, gpio_ports[1]);

    map_exti(r, nvic, gpio_ports);
    map_timers(chip, r, DEVICE(&STM32F405_SOC(soc)->armv7m), gpio_ports, dma);
    map_usarts(chip, r, DEVICE(&STM32F405_SOC(soc)->armv7m), dma);
    map_adcs(chip, r, nvic, dma[1]);
    wire_pins(chip, gpio_ports);
    map_absent(chip);

    DeviceState *dwt = qdev_new(TYPE_RIG_DWT);
    qdev_connect_clock_in(dwt, "hclk", hclk);
    sysbus_realize_and_unref(SYS_BUS_DEVICE(dwt), &error_fatal);
    memory_region_add_subregion_overlap(&STM32F405_SOC(soc)->armv7m.container, DWT_BASE,
                                        sysbus_mmio_get_region(SYS_BUS_DEVICE(dwt), 0), 0);

    if (chip->ccm_size != 0) {
        MemoryRegion *ccm = g_new0(MemoryRegion, 1);
        memory_region_init_ram(ccm, NULL, "rig-stm32f4.ccm", chip->ccm_size, &error_fatal);
        memory_region_add_subregion(get_system_memory(), CCM_BASE, ccm);
    }
    armv7m_load_kernel(ARM_CPU(first_cpu), machine->kernel_filename, 0, chip->flash_size);
}

static char *get_wires(Object *obj, Error **errp) { return g_strdup(wires_spec ? wires_spec : ""); }

static void set_wires(Object *obj, const char *value, Error **errp)
{
    g_free(wires_spec);
    wires_spec = g_strdup(value);
}

void rig_stm32f4_machine_class_init(MachineClass *mc, const char *desc)
{
    mc->desc = desc;
    object_class_property_add_str(OBJECT_CLASS(mc), "wires", get_wires, set_wires);
    object_class_property_set_description(OBJECT_CLASS(mc), "wires",
                                          "pins joined, each pair driver-driven: PD12-PA0[+PB0-PC1...]");
}

/* The STM32F405 (RM0090, DS8626): everything QEMU's SoC and the models have, its SRAM as the chip's 128 KB
 * (SRAM1 and SRAM2) and the other 64 KB as the CCM data RAM at 0x10000000 */
static const RigStm32Region f405_absent[] = {
    { 0x20000000 + SRAM_SIZE_F4, 64 * 1024, "SRAM beyond the F405's 128 KB (its CCM RAM is at 0x10000000)" },
};

static const RigStm32Chip f405 = {
    .name = "rig-stm32f405",
    .part = 405,
    .flash_size = 1024 * 1024,
    .ccm_size = 64 * 1024,
    .absent = f405_absent,
    .n_absent = ARRAY_SIZE(f405_absent),
    .timers = 0x7FFE, /* TIM1..TIM14 */
    .usarts = 0x7E,   /* USART1..USART6 */
    .adcs = 3,
    .port_pins = { 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF },
};

static void rig_stm32f405_init(MachineState *machine) { rig_stm32f4_machine_init(machine, &f405); }

static void rig_stm32f405_machine_init(MachineClass *mc)
{
    rig_stm32f4_machine_class_init(
        mc, "STM32F405 with the rig's RCC, PWR, FLASH, GPIO, DMA, I2C, timer and DWT models and a GY-86 on I2C1");
    mc->init = rig_stm32f405_init;
}

DEFINE_MACHINE("rig-stm32f405", rig_stm32f405_machine_init)
