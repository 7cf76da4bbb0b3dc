/*
 * Which pins carry I2C1: RM0090's alternate-function map (the STM32F405 datasheet's table 9, and the
 * F411's, RM0383/DS10314) gives I2C1_SCL and I2C1_SDA on AF4 at two pairs of port B pins, PB6/PB7 and
 * PB8/PB9. The controller's lines follow the pair the firmware's AFR last set to AF4 (kept while the pins
 * leave AF mode, as for a bus unstick by GPIO: the board's bus stays wired to the pins it uses); the
 * bus's drive (its pull-ups, a slave holding SDA) reaches that pair. The pairs are a table, not branches.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/irq.h"
#include "rig_stm32f4.h"

#define I2C1_AF 4
#define LINES 2 /* SCL, SDA */

/* RM0090 / DS8626 table 9: the port B pins I2C1 may use, SCL then SDA */
static const uint8_t i2c1_pin_pairs[][LINES] = { { 6, 7 }, { 8, 9 } };
#define PAIRS ARRAY_SIZE(i2c1_pin_pairs)

typedef struct I2c1Route {
    DeviceState *gpiob;
    qemu_irq controller_line[LINES];
    unsigned pair;            /* the pair that last selected AF4 */
    bool level[PAIRS][LINES]; /* each candidate pin's level */
    bool drive[LINES];        /* the bus's drive: 1 released, 0 held low */
} I2c1Route;

static void drive_selected(I2c1Route *r)
{
    for (unsigned line = 0; line < LINES; line++) {
        qemu_set_irq(qdev_get_gpio_in(r->gpiob, i2c1_pin_pairs[r->pair][line]), r->drive[line]);
    }
}

static void show_selected(I2c1Route *r)
{
    for (unsigned line = 0; line < LINES; line++) {
        qemu_set_irq(r->controller_line[line], r->level[r->pair][line]);
    }
}

/* A candidate pin's level (n: pair * 2 + line) */
static void pin_changed(void *opaque, int n, int level)
{
    I2c1Route *r = opaque;
    r->level[n / LINES][n % LINES] = level;
    if ((unsigned)n / LINES == r->pair) {
        qemu_set_irq(r->controller_line[n % LINES], level);
    }
}

/* The GPIO's "af-input" for a candidate pin on AF4: that pin now selects I2C1 */
static void pin_selects_i2c1(void *opaque, int n, int level)
{
    I2c1Route *r = opaque;
    if ((unsigned)n / LINES != r->pair) {
        r->pair = n / LINES;
        show_selected(r);
        drive_selected(r);
    }
}

static void bus_drives(void *opaque, int line, int level)
{
    I2c1Route *r = opaque;
    r->drive[line] = level;
    qemu_set_irq(qdev_get_gpio_in(r->gpiob, i2c1_pin_pairs[r->pair][line]), level);
}

void rig_stm32_route_i2c1(DeviceState *i2c1, DeviceState *gpiob)
{
    I2c1Route *r = g_new0(I2c1Route, 1);
    r->gpiob = gpiob;
    qemu_irq *pins = qemu_allocate_irqs(pin_changed, r, PAIRS * LINES);
    qemu_irq *selects = qemu_allocate_irqs(pin_selects_i2c1, r, PAIRS * LINES);
    qemu_irq *drives = qemu_allocate_irqs(bus_drives, r, LINES);
    for (unsigned line = 0; line < LINES; line++) {
        r->controller_line[line] = qdev_get_gpio_in_named(i2c1, "scl-sda", line);
        r->drive[line] = true;
        qdev_connect_gpio_out_named(i2c1, "scl-sda-drive", line, drives[line]);
        for (unsigned pair = 0; pair < PAIRS; pair++) {
            unsigned pin = i2c1_pin_pairs[pair][line];
            r->level[pair][line] = true;
            qdev_connect_gpio_out(gpiob, pin, pins[pair * LINES + line]);
            qdev_connect_gpio_out_named(gpiob, "af-input", RIG_GPIO_AF_LINE(pin, I2C1_AF),
                                        selects[pair * LINES + line]);
        }
    }
}
