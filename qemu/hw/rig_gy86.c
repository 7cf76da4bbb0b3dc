/*
 * The GY-86 sensor board on an I2C bus: the rig's chip core (emulators/chips, compiled in as hw/rig/chips;
 * MIT-licensed, combined here into QEMU under the GPL) in its GY-86 topology, the MPU-6050 at 0x68 with
 * the HMC5883L at 0x1E behind the MPU's bypass and the MS5611 at 0x77. One QEMU I2C slave stands for the
 * whole board: it takes every address to the chip core, whose chip_start acknowledges or not (an absent
 * address is NACKed and counted there, CHIP_COUNT_NACKS), and maps the bus events one to one:
 * START -> chip_start (at the virtual time), a byte written -> chip_write_byte, a byte read ->
 * chip_read_byte, the end of the transfer -> chip_stop.
 *
 * Alone, the samples are the chip core's at-rest ones (nothing is pushed: a static world). Linked to the
 * rig's session (its "link" property, rig_link.c), the events go to the session's chip core instead, fed
 * by the world: one chip core, the lockstep session's, answers both tiers.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "../chips/chip_core.h"
#include "hw/qdev-properties.h"
#include "qemu/module.h"
#include "qemu/timer.h"
#include "rig_stm32f4.h"

OBJECT_DECLARE_SIMPLE_TYPE(RigGy86State, RIG_GY86)

struct RigGy86State {
    I2CSlave parent_obj;
    chip_board board;
    uint8_t address; /* the 7-bit address of the transfer being started */
    RigLinkState *link;
};

/* Every address is the board's to answer: the chip core decides at the START */
static bool gy86_match(I2CSlave *candidate, uint8_t address, bool broadcast, I2CNodeList *current_devs)
{
    I2CNode *node = g_new(I2CNode, 1);
    RIG_GY86(candidate)->address = address;
    node->elt = candidate;
    QLIST_INSERT_HEAD(current_devs, node, next);
    return true;
}

static int gy86_event(I2CSlave *slave, enum i2c_event event)
{
    RigGy86State *s = RIG_GY86(slave);
    uint64_t now_ns = (uint64_t)rig_i2c_now_ns(); /* the instant on the wire */
    if (event == I2C_FINISH && rig_i2c_repeated_start) {
        return 0; /* the START that follows tells the chips */
    }
    if (s->link != NULL) {
        switch (event) {
        case I2C_START_RECV:
        case I2C_START_SEND:
        case I2C_START_SEND_ASYNC:
            return rig_link_i2c_start(s->link, now_ns, s->address, event == I2C_START_RECV) ? 0 : 1;
        case I2C_FINISH:
            rig_link_i2c_stop(s->link);
            return 0;
        case I2C_NACK:
            rig_link_i2c_nack(s->link);
            return 0;
        }
        return 0;
    }
    switch (event) {
    case I2C_START_RECV:
    case I2C_START_SEND:
    case I2C_START_SEND_ASYNC:
        return chip_start(&s->board, now_ns, s->address, event == I2C_START_RECV) ? 0 : 1;
    case I2C_FINISH:
        chip_stop(&s->board);
        return 0;
    case I2C_NACK:
        return 0;
    }
    return 0;
}

static int gy86_send(I2CSlave *slave, uint8_t byte)
{
    RigGy86State *s = RIG_GY86(slave);
    if (s->link != NULL) {
        rig_link_i2c_write(s->link, byte);
    } else {
        chip_write_byte(&s->board, byte);
    }
    return 0;
}

static uint8_t gy86_recv(I2CSlave *slave)
{
    RigGy86State *s = RIG_GY86(slave);
    return s->link != NULL ? rig_link_i2c_read(s->link) : chip_read_byte(&s->board);
}

static void gy86_realize(DeviceState *dev, Error **errp)
{
    chip_board_init(&RIG_GY86(dev)->board, CHIP_TOPOLOGY_GY86); /* power-on, at virtual time 0 */
}

static Property gy86_properties[] = {
    DEFINE_PROP_LINK("link", RigGy86State, link, TYPE_RIG_LINK, RigLinkState *),
    DEFINE_PROP_END_OF_LIST(),
};

static void gy86_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    device_class_set_props(dc, gy86_properties);
    I2CSlaveClass *sc = I2C_SLAVE_CLASS(klass);
    dc->realize = gy86_realize;
    sc->match_and_add = gy86_match;
    sc->event = gy86_event;
    sc->send = gy86_send;
    sc->recv = gy86_recv;
}

static const TypeInfo gy86_info = {
    .name = TYPE_RIG_GY86,
    .parent = TYPE_I2C_SLAVE,
    .instance_size = sizeof(RigGy86State),
    .class_init = gy86_class_init,
};

static void gy86_register_types(void) { type_register_static(&gy86_info); }

type_init(gy86_register_types)
