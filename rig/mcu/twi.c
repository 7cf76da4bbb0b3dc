/* The TWI master of the ATmega328P and ATmega2560, ours instead of simavr 1.6's: simavr clocks every byte
 * at 9 us whatever TWBR says, reports SLA+W as a data byte (0x28 for 0x18), and expects a target to answer
 * inside its register write, where the engine cannot stop for a sample. Here a byte takes the nine SCL
 * periods that TWBR and the prescaler give (16 + 2 TWBR 4^TWPS CPU cycles each), START and STOP one
 * period; the status codes are the datasheet's; each byte is done by a glue event, between two
 * instructions, where the chip core may ask for a sample first (demand mode).
 *
 * The chip core sees a transfer as the Linux I2C path does: one time for all of it, its first START's;
 * a repeated START does not move time (chip_start at the same time does not sample again). Slave mode is
 * not modelled: the rig's board has no second master. */
#include <stdlib.h>
#include <string.h>

#include <simavr/avr_twi.h>
#include <simavr/sim_io.h>

#include "glue.h"

/* data-space addresses, the same on both MCUs */
#define TWBR 0xB8
#define TWSR 0xB9
#define TWDR 0xBB
#define TWCR 0xBC

#define TWINT 0x80
#define TWEA 0x40
#define TWSTA 0x20
#define TWSTO 0x10
#define TWWC 0x08
#define TWEN 0x04
#define TWIE 0x01

/* the bus as the master sees it */
enum { IDLE, STARTED, WRITING, READING, NACKED };
/* the operation under way */
enum { EV_NONE, EV_START, EV_ADDR, EV_WRITE, EV_READ, EV_STOP };

static uint64_t bit_cycles(const avr_t *avr)
{
    static const uint32_t prescale[4] = { 1, 4, 16, 64 };
    return 16u + 2u * avr->data[TWBR] * prescale[avr->data[TWSR] & 3];
}

static void record(mcu_engine *e, uint8_t kind, uint8_t value, uint8_t ack)
{
    mcu_twi *t = &e->twi;
    mcu_twi_record ev = { .t_ns = mcu_ns(e, e->avr->cycle), .kind = kind, .value = value, .ack = ack };
    if (t->n_cur < MCU_TWI_EVENTS)
        t->cur[t->n_cur++] = ev;
    if (t->log_on) {
        if (t->n_log == t->cap_log) {
            uint32_t cap = t->cap_log ? 2 * t->cap_log : 1024;
            mcu_twi_record *log = realloc(t->log, cap * sizeof *log);
            if (!log)
                return;
            t->log = log;
            t->cap_log = cap;
        }
        t->log[t->n_log++] = ev;
    }
}

static void end_transfer(mcu_engine *e)
{
    mcu_twi *t = &e->twi;
    if (!t->in_transfer)
        return;
    record(e, 'P', 0, 0);
    if (e->board && t->acked)
        e->chip.stop(e->board);
    memcpy(t->last, t->cur, t->n_cur * sizeof t->cur[0]);
    t->n_last = t->n_cur;
    t->n_cur = 0;
    t->in_transfer = false;
    t->acked = false;
}

static void status(mcu_engine *e, uint8_t code, bool interrupt)
{
    avr_t *avr = e->avr;
    mcu_twi *t = &e->twi;
    avr->data[TWSR] = (uint8_t)((avr->data[TWSR] & 3) | code);
    if (!interrupt)
        return;
    avr_raise_interrupt(avr, e->twi_vector);
    t->awaiting = false;
    if (code == 0x00)
        t->bus_errors++;
    else if (code == 0x38 || code == 0x68 || code == 0x78 || code == 0xB0)
        t->arbitration_lost++;
}

static void schedule(mcu_engine *e, uint8_t event, uint64_t bits)
{
    if (event != EV_STOP)
        e->twi.awaiting = true;
    e->twi.event = event;
    e->twi.event_cycle = e->avr->cycle + bits * bit_cycles(e->avr);
    mcu_reschedule(e);
}

/* A TWCR write while the unit is busy (TWINT clear, an operation on the bus), per the datasheet's words
 * (ATmega2560 2549Q and ATmega328P, "2-wire Serial Interface", TWCR):
 * - TWSTA during a STOP: "if the bus is not free, the TWI waits until a STOP condition is detected, and
 *   then generates a new START condition": the START is kept and follows the STOP (MultiWii's
 *   i2c_stop(); i2c_rep_start(); writes exactly this);
 * - TWSTO during a STOP: "When the STOP condition is executed on the bus, the TWSTO bit is cleared
 *   automatically": the request joins the STOP under way, one STOP on the bus;
 * - TWEA at any time: the bit only; "the ACK pulse is generated ... if ... A data byte has been received
 *   in Master Receiver ... mode", so a received byte's ACK is the bit when the byte ends (EV_READ);
 * - anything else with TWINT written during a START or a byte: "Writing a one to TWINT clears the flag.
 *   The TWI will then commence executing whatever operation was specified": the flag is already clear,
 *   nothing new starts; the rig counts the request as ignored. */
static void busy_write(mcu_engine *e, uint8_t v, uint8_t old)
{
    mcu_twi *t = &e->twi;
    bool start = (v & TWSTA) && ((v & TWINT) || !(old & TWSTA));
    if (t->event == EV_STOP) {
        e->avr->data[TWCR] |= TWSTO; /* (cleared when the STOP is executed) */
        if (start)
            t->start_after = t->awaiting = true;
        else if ((v & TWINT) && !(v & TWSTO))
            t->ignored++; /* a byte asked for while the bus is being let go */
        return;
    }
    if ((v & TWINT) || start)
        t->ignored++;
}

static void twcr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    mcu_engine *e = param;
    mcu_twi *t = &e->twi;
    uint8_t old = avr->data[addr];
    avr->data[addr] = (uint8_t)((v & ~(TWINT | TWWC)) | (old & (TWINT | TWWC)));
    if (!(v & TWEN)) { /* off: "all TWI transmissions are terminated, regardless of any ongoing operation" */
        if (t->in_transfer)
            end_transfer(e);
        avr_clear_interrupt(avr, e->twi_vector);
        avr->data[addr] &= (uint8_t)~TWINT;
        if (t->awaiting) /* a wait for TWINT given up (MultiWii: TWCR = 0 after 255 polls) */
            t->abandoned++;
        t->awaiting = false;
        t->state = IDLE;
        t->event = EV_NONE;
        t->start_after = false;
        status(e, 0xF8, false);
        return;
    }
    if ((v & TWIE) && !(old & TWIE) && (old & TWINT))
        avr_raise_interrupt(avr, e->twi_vector);
    if (t->event != EV_NONE) {
        busy_write(e, v, old);
        return;
    }
    bool go = (v & TWINT) || (t->state == IDLE && (v & TWSTA) && !(old & TWSTA));
    if (!go)
        return;
    avr_clear_interrupt(avr, e->twi_vector); /* (TWINT is a sticky flag to simavr: cleared here) */
    avr->data[addr] &= (uint8_t) ~(TWINT | TWWC);
    /* "The TWSR only contains relevant status information when the TWI Interrupt Flag is asserted. At all
     * other times, the TWSR contains a special status code": 0xF8 */
    status(e, 0xF8, false);
    if (v & TWSTO) {
        end_transfer(e);
        t->state = IDLE;
        t->start_after = t->awaiting = (v & TWSTA) != 0;
        schedule(e, EV_STOP, 1);
    } else if (v & TWSTA) {
        schedule(e, EV_START, 1);
    } else if (t->state == STARTED) {
        t->sla = avr->data[TWDR];
        schedule(e, EV_ADDR, 9);
    } else if (t->state == WRITING || t->state == NACKED) {
        schedule(e, EV_WRITE, 9);
    } else if (t->state == READING) {
        schedule(e, EV_READ, 9);
    } else {
        t->ignored++; /* a byte with no START: no bus to send it on */
    }
}

static void twdr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    mcu_engine *e = param;
    if (e->twi.event != EV_NONE && !(avr->data[TWCR] & TWINT)) { /* written while a byte is on the bus */
        avr->data[TWCR] |= TWWC;
        e->twi.collisions++;
        return;
    }
    avr->data[addr] = v;
}

static void twsr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)param;
    avr->data[addr] = (uint8_t)((avr->data[addr] & 0xF8) | (v & 3));
}

void mcu_twi_attach(mcu_engine *e)
{
    avr_t *avr = e->avr;
    for (avr_io_t *port = avr->io_port; port; port = port->next)
        if (!strcmp(port->kind, "twi"))
            e->twi_vector = &((avr_twi_t *)port)->twi;
    avr->io[AVR_DATA_TO_IO(TWCR)].w.c = twcr_write;
    avr->io[AVR_DATA_TO_IO(TWCR)].w.param = e;
    avr->io[AVR_DATA_TO_IO(TWDR)].w.c = twdr_write;
    avr->io[AVR_DATA_TO_IO(TWDR)].w.param = e;
    avr->io[AVR_DATA_TO_IO(TWDR)].r.c = NULL;
    avr->io[AVR_DATA_TO_IO(TWSR)].w.c = twsr_write;
    avr->io[AVR_DATA_TO_IO(TWSR)].w.param = e;
    mcu_twi_reset(e);
}

void mcu_twi_reset(mcu_engine *e)
{
    mcu_twi *t = &e->twi;
    if (t->in_transfer)
        end_transfer(e);
    t->state = IDLE;
    t->event = EV_NONE;
    t->start_after = t->awaiting = false;
    e->avr->data[TWSR] = 0xF8;
    e->avr->data[TWDR] = 0xFF;
}

/* the operation under way is done: MCU_NEED when the chip core lacks a sample (nothing changed: run
 * again once it is served), else 0 */
int mcu_twi_event(mcu_engine *e)
{
    avr_t *avr = e->avr;
    mcu_twi *t = &e->twi;
    uint8_t ev = t->event;
    switch (ev) {
    case EV_START:
        if (!t->in_transfer) {
            t->in_transfer = true;
            t->start_ns = mcu_ns(e, avr->cycle);
            t->n_cur = 0;
        }
        record(e, 'S', 0, 0);
        status(e, t->state == IDLE ? 0x08 : 0x10, true);
        t->state = STARTED;
        break;
    case EV_ADDR: {
        bool read = t->sla & 1, ack = false;
        if (e->board) {
            chip_need need = e->chip.advance(e->board, t->start_ns);
            if (need.chip != CHIP_NONE) {
                e->need = need;
                return MCU_NEED;
            }
            ack = e->chip.start(e->board, t->start_ns, t->sla >> 1, read);
        }
        t->acked = ack;
        t->transactions++;
        e->last_activity = avr->cycle;
        record(e, 'A', t->sla, ack);
        if (ack) {
            t->nacks_in_row = 0;
            t->nack_since_cycle = MCU_NEVER;
        } else {
            t->nacks++;
            if (t->nacks_in_row++ == 0) {
                t->nack_since_cycle = avr->cycle;
                mcu_deadline(e);
            }
        }
        status(e, read ? (ack ? 0x40 : 0x48) : (ack ? 0x18 : 0x20), true);
        t->state = ack ? (read ? READING : WRITING) : NACKED;
        break;
    }
    case EV_WRITE: {
        uint8_t byte = avr->data[TWDR];
        bool ack = t->state == WRITING && t->acked;
        if (ack && e->board)
            e->chip.write_byte(e->board, byte);
        t->bytes++;
        if (!ack)
            t->data_nacks++;
        record(e, 'W', byte, ack);
        status(e, ack ? 0x28 : 0x30, true);
        break;
    }
    case EV_READ: {
        bool master_ack = (avr->data[TWCR] & TWEA) != 0;
        uint8_t byte = t->acked && e->board ? e->chip.read_byte(e->board) : 0xFF;
        avr->data[TWDR] = byte;
        t->bytes++;
        record(e, 'R', byte, master_ack);
        status(e, master_ack ? 0x50 : 0x58, true);
        break;
    }
    case EV_STOP:
        avr->data[TWCR] &= (uint8_t)~TWSTO;
        status(e, 0xF8, false);
        if (t->start_after) {
            t->start_after = false;
            schedule(e, EV_START, 1);
            return 0;
        }
        break;
    default:
        break;
    }
    t->event = EV_NONE;
    return 0;
}

/* the records of the last finished transfer (out: MCU_TWI_EVENTS) */
MCU_API uint32_t mcu_twi_last(const mcu_engine *e, mcu_twi_record *out)
{
    memcpy(out, e->twi.last, e->twi.n_last * sizeof *out);
    return e->twi.n_last;
}

MCU_API void mcu_twi_log(mcu_engine *e, bool on) { e->twi.log_on = on; }

/* moves up to max records of the log into out; returns how many */
MCU_API uint32_t mcu_twi_take(mcu_engine *e, mcu_twi_record *out, uint32_t max)
{
    mcu_twi *t = &e->twi;
    uint32_t n = t->n_log < max ? t->n_log : max;
    memcpy(out, t->log, n * sizeof *out);
    memmove(t->log, t->log + n, (t->n_log - n) * sizeof *out);
    t->n_log -= n;
    return n;
}
