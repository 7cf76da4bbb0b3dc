/* Bytes into the USARTs at frame timing and out of them, and pin schedules (glue.h).
 *
 * A byte sent to USARTn is on the line for one frame (start, 8 data, parity, stops at the sender's
 * baud), the next one right after it. It goes into simavr's receiver as its start bit begins: simavr
 * makes it readable (RXC) one of its byte times later, which the glue keeps equal to the receiver's
 * frame, so a byte is read when its last stop bit ends. The receiver takes it when its set-up reads
 * the line's frame: the rate within the receiver's tolerance (UBRR, U2X), the same parity (the second
 * stop bit the receiver never checks, as the hardware); otherwise the byte is a frame error on the
 * real line, counted, and not delivered. A byte that arrives while the receiver is disabled (RXEN
 * clear: a firmware not yet set up) is lost without a trace on the hardware: counted apart.
 *
 * A pin schedule drives an input pin to given levels at given cycles (a PPM sum): an edge on an INTx or
 * PCINT pin interrupts as on the hardware. simavr 1.6's ATmega2560 has pin change interrupts on port B
 * only: the glue adds PCINT1 (PJ0-PJ6, PCINT9-15) and PCINT2 (port K, PCINT16-23), where Mega flight
 * controllers take PWM receivers. */
#include <string.h>

#include <simavr/avr_adc.h>
#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_io.h>

#include "glue.h"

static void tx_byte(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    mcu_uart *u = param;
    u->engine->last_activity = u->engine->avr->cycle; /* (a firmware that talks is not hung) */
    if (u->n_tx == MCU_TX_BYTES) {
        u->tx_dropped++;
        return;
    }
    u->tx[u->n_tx++] = (uint8_t)value;
}

/* simavr 1.6 computes its byte time at a UBRR write only, with a parity bit whether there is one or not:
 * after every write to the set-up registers it is the frame's again (1 + data + parity + stops bits) */
static void frame_time(mcu_uart *u)
{
    const uint8_t *d = u->engine->avr->data;
    uint8_t a = d[u->base], b = d[u->base + 1], c = d[u->base + 2];
    uint32_t ubrr = (uint32_t)(d[u->base + 4] | (d[u->base + 5] & 0x0F) << 8);
    static const uint8_t data_bits[8] = { 5, 6, 7, 8, 8, 8, 8, 9 };
    uint32_t bits = 1u + data_bits[(c >> 1 & 3) | (b & 0x04)] + ((c >> 4 & 3) >= 2) + 1u + (c >> 3 & 1);
    ((avr_uart_t *)u->port)->cycles_per_byte = (ubrr + 1u) * ((a & 0x02) ? 8u : 16u) * bits;
}

static void setup_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    mcu_uart *u = param;
    int k = addr - u->base;
    if (u->orig[k])
        u->orig[k](avr, addr, v, u->orig_param[k]);
    else
        avr->data[addr] = v;
    frame_time(u);
}

/* USARTn ('0'..'3') at UCSRnA = base; false when simavr has no such USART */
MCU_API bool mcu_uart_define(mcu_engine *e, uint8_t n, uint16_t base)
{
    if (n >= MCU_UARTS)
        return false;
    mcu_uart *u = &e->uarts[n];
    avr_irq_t *in = avr_io_getirq(e->avr, AVR_IOCTL_UART_GETIRQ('0' + n), UART_IRQ_INPUT);
    avr_irq_t *out = avr_io_getirq(e->avr, AVR_IOCTL_UART_GETIRQ('0' + n), UART_IRQ_OUTPUT);
    if (!in || !out)
        return false;
    uint32_t flags = 0; /* simavr's defaults: a usleep(1) per poll of an idle UCSRnA, stdout echo */
    avr_ioctl(e->avr, AVR_IOCTL_UART_SET_FLAGS('0' + n), &flags);
    memset(u, 0, sizeof *u);
    u->used = true;
    u->engine = e;
    u->base = base;
    u->irq = in;
    u->next = MCU_NEVER;
    for (avr_io_t *port = e->avr->io_port; port; port = port->next)
        if (!strcmp(port->kind, "uart") && ((avr_uart_t *)port)->name == '0' + n)
            u->port = port;
    if (!u->port)
        return false;
    for (int k = 0; k < 6; k++) {
        if (k == 3)
            continue;
        int io = AVR_DATA_TO_IO(base + k);
        u->orig[k] = e->avr->io[io].w.c;
        u->orig_param[k] = e->avr->io[io].w.param;
        e->avr->io[io].w.c = setup_write;
        e->avr->io[io].w.param = u;
    }
    frame_time(u);
    avr_irq_register_notify(out, tx_byte, u);
    return true;
}

/* queues bytes from now on, one frame apart; false when the queue is full (nothing queued) */
MCU_API bool mcu_uart_send(mcu_engine *e, uint8_t n, const uint8_t *data, uint32_t len, uint32_t baud, char parity,
                           uint8_t stop_bits)
{
    mcu_uart *u = &e->uarts[n];
    if (!u->used || len > MCU_RX_BYTES - u->len || !baud)
        return false;
    uint64_t bits = 1 + 8 + (parity != 'N') + stop_bits;
    uint64_t frame = (bits * e->clock_hz + baud / 2) / baud;
    if (u->len == 0)
        u->next = e->avr->cycle;
    u->frame_cycles = frame;
    u->baud = baud;
    u->parity = (uint8_t)parity;
    u->stop_bits = stop_bits;
    for (uint32_t i = 0; i < len; i++)
        u->bytes[(u->head + u->len + i) % MCU_RX_BYTES] = data[i];
    u->len += len;
    mcu_reschedule(e);
    return true;
}

/* the receiver reads the line's frames as they are sent: 8 data bits, the same parity, and the line's
 * rate within the receiver's tolerance (the datasheets' "maximum receiver baud rate error" table, for 8
 * data bits with or without parity, normal or double speed), in 1/10000 of the receiver's rate */
static bool same_frame(const mcu_engine *e, const mcu_uart *u)
{
    static const uint16_t slow[2][2] = { { 9536, 9581 }, { 9600, 9639 } },
                          fast[2][2] = { { 10458, 10414 }, { 10390, 10353 } };
    const uint8_t *d = e->avr->data;
    uint8_t a = d[u->base], b = d[u->base + 1], c = d[u->base + 2];
    uint32_t ubrr = (uint32_t)(d[u->base + 4] | (d[u->base + 5] & 0x0F) << 8);
    bool u2x = (a & 0x02) != 0;
    uint64_t rx_bit = (ubrr + 1u) * (u2x ? 8u : 16u);
    uint8_t upm = c >> 4 & 3, size = (uint8_t)((c >> 1 & 3) | (b & 0x04));
    char parity = upm == 2 ? 'E' : upm == 3 ? 'O' : 'N';
    uint64_t ratio = rx_bit * u->baud * 10000u / e->clock_hz; /* the line's rate over the receiver's */
    bool p = parity != 'N';
    return size == 3 && parity == (char)u->parity && ratio >= slow[u2x][p] && ratio <= fast[u2x][p];
}

uint64_t mcu_serial_next(const mcu_engine *e)
{
    uint64_t next = MCU_NEVER;
    for (int i = 0; i < MCU_UARTS; i++)
        if (e->uarts[i].used && e->uarts[i].len && e->uarts[i].next < next)
            next = e->uarts[i].next;
    for (int i = 0; i < MCU_DRIVEN_PINS; i++)
        if (e->pins[i].used && e->pins[i].len && e->pins[i].edges[e->pins[i].head].cycle < next)
            next = e->pins[i].edges[e->pins[i].head].cycle;
    return next;
}

void mcu_serial_event(mcu_engine *e)
{
    uint64_t now = e->avr->cycle;
    for (int i = 0; i < MCU_UARTS; i++) {
        mcu_uart *u = &e->uarts[i];
        while (u->used && u->len && u->next <= now) {
            uint8_t byte = u->bytes[u->head];
            u->head = (u->head + 1) % MCU_RX_BYTES;
            u->len--;
            if (!(e->avr->data[u->base + 1] & 0x10)) { /* UCSRnB's RXENn */
                u->receiver_off++;
            } else if (same_frame(e, u)) {
                avr_raise_irq((avr_irq_t *)u->irq, byte);
                u->delivered++;
            } else {
                u->frame_errors++;
            }
            u->next += u->frame_cycles;
        }
    }
    for (int i = 0; i < MCU_DRIVEN_PINS; i++) {
        mcu_pin *p = &e->pins[i];
        while (p->used && p->len && p->edges[p->head].cycle <= now) {
            avr_irq_t *irq = avr_io_getirq(e->avr, AVR_IOCTL_IOPORT_GETIRQ(p->port), p->bit);
            avr_raise_irq(irq, p->edges[p->head].level);
            p->head = (p->head + 1) % MCU_PIN_EDGES;
            p->len--;
        }
    }
}

MCU_API uint32_t mcu_uart_take(mcu_engine *e, uint8_t n, uint8_t *out, uint32_t max)
{
    mcu_uart *u = &e->uarts[n];
    uint32_t k = u->n_tx < max ? u->n_tx : max;
    memcpy(out, u->tx, k);
    memmove(u->tx, u->tx + k, u->n_tx - k);
    u->n_tx -= k;
    return k;
}

MCU_API uint32_t mcu_uart_count(const mcu_engine *e, uint8_t n, int which)
{
    const mcu_uart *u = &e->uarts[n];
    return which == 0   ? u->delivered
           : which == 1 ? u->frame_errors
           : which == 2 ? u->len
           : which == 3 ? u->tx_dropped
                        : u->receiver_off;
}

/* levels at cycles (ascending, from now on) on an input pin; slot 0..3 per pin; false when full */
MCU_API bool mcu_pin_drive(mcu_engine *e, char port, uint8_t bit, const uint64_t *cycles, const uint8_t *levels,
                           uint32_t n)
{
    mcu_pin *p = NULL;
    for (int i = 0; i < MCU_DRIVEN_PINS && !p; i++)
        if (e->pins[i].used && e->pins[i].port == (uint8_t)port && e->pins[i].bit == bit)
            p = &e->pins[i];
    for (int i = 0; i < MCU_DRIVEN_PINS && !p; i++)
        if (!e->pins[i].used) {
            p = &e->pins[i];
            *p = (mcu_pin){ .used = true, .port = (uint8_t)port, .bit = bit };
        }
    if (!p || n > MCU_PIN_EDGES - p->len || !avr_io_getirq(e->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit))
        return false;
    for (uint32_t i = 0; i < n; i++)
        p->edges[(p->head + p->len + i) % MCU_PIN_EDGES] = (mcu_edge){ cycles[i], levels[i] };
    p->len += n;
    mcu_reschedule(e);
    return true;
}

#define PCICR_2560 0x68
#define PCIFR_2560 0x3B
#define PCMSK1_2560 0x6C

static void pcint_changed(struct avr_irq_t *irq, uint32_t value, void *param)
{
    mcu_pcint_pin *p = param;
    avr_t *avr = p->engine->avr;
    if (!value == !irq->value)
        return;
    if (avr->data[PCMSK1_2560 + p->group - 1] & p->mask)
        avr_raise_interrupt(avr, &p->engine->pcint[p->group]);
}

void mcu_pcint_attach(mcu_engine *e)
{
    avr_t *avr = e->avr;
    if (strcmp(avr->mmcu, "atmega2560"))
        return;
    int k = 0;
    for (uint8_t group = 1; group <= 2; group++) {
        avr_int_vector_t *v = &e->pcint[group];
        *v = (avr_int_vector_t){ .vector = (uint8_t)(9 + group), /* PCINT1_vect 10, PCINT2_vect 11 */
                                 .enable = AVR_IO_REGBIT(PCICR_2560, group),
                                 .raised = AVR_IO_REGBIT(PCIFR_2560, group) };
        avr_register_vector(avr, v);
        for (uint8_t bit = 0; bit < (group == 1 ? 7 : 8); bit++) {
            avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(group == 1 ? 'J' : 'K'), bit);
            if (!irq)
                continue;
            mcu_pcint_pin *p = &e->pcint_pins[k++];
            *p = (mcu_pcint_pin){ e, group, (uint8_t)(group == 1 ? 1u << (bit + 1) : 1u << bit) };
            avr_irq_register_notify(irq, pcint_changed, p);
        }
    }
}

static void output_changed(struct avr_irq_t *irq, uint32_t value, void *param)
{
    mcu_watched_pin *w = param;
    avr_t *avr = w->engine->avr;
    if (value != irq->value && (avr->data[w->ddr] >> w->bit & 1))
        w->engine->last_activity = avr->cycle;
}

/* the hang check counts a change of any output pin of `port` (DDRx at data address `ddr`) as activity:
 * a firmware that blinks a LED or bit-bangs anything is running; a pin driven from outside (DDR bit
 * clear) is not the firmware's doing */
MCU_API bool mcu_watch_port(mcu_engine *e, char port, uint16_t ddr)
{
    for (uint8_t bit = 0; bit < 8; bit++) {
        avr_irq_t *irq = avr_io_getirq(e->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
        if (!irq || e->n_watched == sizeof e->watched / sizeof e->watched[0])
            return false;
        mcu_watched_pin *w = &e->watched[e->n_watched++];
        *w = (mcu_watched_pin){ .engine = e, .ddr = ddr, .bit = bit };
        avr_irq_register_notify(irq, output_changed, w);
    }
    return true;
}

/* an analog input: ADC channel `channel` at `millivolts` from now on (a battery through its divider) */
MCU_API bool mcu_adc_set(mcu_engine *e, uint8_t channel, uint32_t millivolts)
{
    avr_irq_t *irq = avr_io_getirq(e->avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + channel);
    if (!irq || channel > ADC_IRQ_ADC15)
        return false;
    avr_raise_irq(irq, millivolts);
    return true;
}
