/*
 * The rig's link: QEMU in lockstep with the rig's session (rig/mcu/stm32_link.py) over a chardev (a
 * socket the session listens on). The machine creates it when a chardev named "rig-link" exists.
 *
 * Under -icount shift=N,sleep=off virtual time is the instruction count, and everything here happens at
 * an instant of it, read synchronously (the socket is read blocking in the vCPU), so a run is the same
 * every time. The session says "go to t"; a QEMU_CLOCK_VIRTUAL timer at t answers "reached t" with the
 * latched pulses of the board's motor outputs (the timers' chC-high-ticks, period-ticks, clock-hz) and
 * the CPU's state (the exception being handled, pc, CFSR, HFSR: a HardFault ends the run in the session),
 * then blocks for the next command. A system reset (a watchdog's, the firmware's request) is told to the
 * session at its instant with its cause and the CPU's state then (a watchdog's ends the run: QEMU goes
 * no further); between steps the session may read
 * the flash (the settings the firmware keeps there). The I2C bus's events of the GY-86 slave go to the session, whose chip
 * core (the lockstep session's own) answers: a START waits for the answer, a byte written and a STOP do
 * not. The session serves the chip core's sample needs from the world meanwhile.
 *
 * Reads come ahead: a round trip per byte read cost more than everything else of a run (the kernel's
 * time for two blocking socket calls per byte, 8 000 bytes a simulated second for the reference FC), so
 * the answer to a read START, and to a read with nothing ahead, carries the bytes the session expects the
 * master to read (a burst's length, as the same transfer read last time). They are kept here and given
 * to the master one by one at their own instants; which were taken, and when, goes to the session
 * (MSG_I2C_READS) before any other message, so its log is the bus's byte for byte. Bytes the master did
 * not read are dropped at the STOP or the next START, and the session takes its chip core back to where
 * the master left it (a chip's register pointer and FIFO move with each byte read).
 *
 * The USARTs (rig_stm32_usart.c, /machine/usart1..usart6) send into ringbuf chardevs named rig-usart1..
 * rig-usart6: what the firmware sent since the last stop goes to the session before each "reached". Bytes
 * the session gives a USART are frames on its RX line one after another (start, 8 data bits, parity,
 * stop bits at the session's baud) from now, after the bytes before them, handed to the USART at once
 * with their start times; its receiver reads the line with its own set-up, so a sender's wrong baud or
 * parity gives the chip's errors.
 *
 * Input pins the session drives (a PPM sum, a switch) get their levels at the virtual instants the
 * session gives (MSG_PIN_DRIVE), each pin's edges queued as a USART's bytes are, through the GPIO port's
 * outside-driver input (the "pin" outputs, port * 16 + pin, which the machine connects there). An ADC
 * input's volts (MSG_ADC_INPUT: the board's battery through its divider) hold from the message's instant.
 *
 * Messages, both ways: a header of the kind (1 byte), 3 zero bytes and the payload's length (u32), then
 * the payload; little-endian; every length is checked against the kind's (a bad message ends QEMU with
 * an error: the session is gone or broken).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "chardev/char-fe.h"
#include "chardev/char.h"
#include "cpu.h"
#include "hw/irq.h"
#include "hw/qdev-properties-system.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qapi/qapi-commands-char.h"
#include "qemu/bswap.h"
#include "qemu/error-report.h"
#include "qemu/module.h"
#include "qom/object.h"
#include "rig_stm32f4.h"
#include "sysemu/reset.h"

#define LINK_VERSION 2
#define LINK_HEADER 8
#define LINK_MAX_PAYLOAD 1024
#define LINK_MOTORS 8
#define LINK_UARTS 6
#define LINK_UART_CHUNK 512 /* bytes read from a ringbuf at a time (base64 in QEMU's API) */
#define LINK_READS 120      /* bytes read ahead and taken, told in one MSG_I2C_READS (its u64 times) */
#define LINK_PIN_QUEUES 9   /* pins driven at once (a PPM sum; a parallel PWM receiver's 8 channels) */
#define LINK_PIN_EDGES 1024 /* edges waiting per pin (a PPM frame of 8 channels is 18) */
#define LINK_PIN_LINES (RIG_GPIO_PORTS * RIG_GPIO_PINS)
#define LINK_EDGE 9 /* u64 t_ns, u8 level */
/* Messages to the session wait in a buffer until QEMU blocks for an answer (or the buffer is full, or
 * QEMU exits): a socket write per message cost a system call and a wake-up of the session for each of
 * the 7 000 messages a simulated second the reference FC's bus gives, most of which need no answer */
#define LINK_OUT_BYTES (16 * (LINK_HEADER + LINK_MAX_PAYLOAD))
#define LINK_IN_BYTES (4 * (LINK_HEADER + LINK_MAX_PAYLOAD)) /* the session's messages, read in blocks */

/* One USART's receiving side: the frames are handed to the USART as they come, with their start times
 * (the USART holds what its line will carry; a QEMU timer per byte here cost a main-loop wake-up each) */
typedef struct {
    DeviceState *usart;    /* the machine's /machine/usartN (none: the chip lacks it) */
    Chardev *chr;          /* rig-usartN, where the USART puts what it sends */
    int64_t busy_until_ns; /* when the last frame given ends */
} LinkUart;

/* the edges waiting for one driven pin, each with its virtual time */
typedef struct {
    RigLinkState *link;
    QEMUTimer *timer;
    int line; /* port * 16 + pin; -1: a free queue */
    int64_t at_ns[LINK_PIN_EDGES];
    uint8_t level[LINK_PIN_EDGES];
    uint32_t head, len;
} LinkPin;

/* QEMU -> session */
#define MSG_HELLO 'H' /* u16 version */
/* u64 t_ns, u32 ipsr, u32 pc, u32 cfsr, u32 hfsr, u8 n, n x (u32 high_ns, u32 period_ns, u32 periods
 * begun since the last stop, u64 the virtual time the last began) */
#define MSG_REACHED 'R'
#define MSG_I2C_START 'S' /* u64 t_ns, u8 7-bit address, u8 read: answered by MSG_ACK */
#define MSG_I2C_WRITE 'W' /* u64 t_ns, u8 byte */
#define MSG_I2C_READ 'D'  /* u64 t_ns: a byte read with none ahead, answered by MSG_BYTE */
#define MSG_I2C_READS 'd' /* n x u64 t_ns: bytes the master read of those ahead, in order */
#define MSG_I2C_NACK 'N'  /* u64 t_ns: the master NACKs the byte it read last */
#define MSG_I2C_STOP 'P'  /* u64 t_ns */
#define MSG_UART_SENT 'T' /* u8 USART 1..6, the bytes the firmware sent */
/* u64 t_ns, u32 cause (RigResetCause), u32 ipsr, u32 pc, u32 cfsr, u32 hfsr: the chip resets (not at
 * power-on), its CPU's state as the reset came */
#define MSG_RESET 'X'
/* session -> QEMU */
#define MSG_CONFIG 'C' /* u8 n, n x (u8 timer 1..14, u8 output 0..6: CH1..CH4, CH1N..CH3N) */
#define MSG_GO 'G'     /* u64 t_ns: run until then */
/* u8 USART 1..6, 3 zero bytes, u32 frame_ns, u32 baud, u8 parity ('N', 'E', 'O'), u8 stop bits (1, 2), 2 zero
 * bytes, the bytes (from now, after those queued, one each frame_ns) */
#define MSG_UART_RX 'U'
#define UART_RX_HEADER 16
#define MSG_QUIT 'Q' /* (none) */
/* u8 port 0..8 (A..I), u8 pin 0..15, 2 zero bytes, n x (u64 t_ns, u8 level): edges from now on, ascending,
 * after those queued */
#define MSG_PIN_DRIVE 'I'
/* u8 ADC 1..3, u8 channel 0..15, 2 zero bytes, u32 microvolts: that input's volts from now on */
#define MSG_ADC_INPUT 'A'
#define MSG_ACK 'a'  /* u8 acknowledged, then the bytes ahead (a read START) */
#define MSG_BYTE 'b' /* the byte read, then the bytes ahead */
/* u32 address, u32 length (at most 1024, within the flash): answered by an 'M' of the flash's bytes there,
 * as the firmware left them (the settings it keeps in flash) */
#define MSG_MEMORY 'M'
#define FLASH_BASE 0x08000000u

OBJECT_DECLARE_SIMPLE_TYPE(RigLinkState, RIG_LINK)

struct RigLinkState {
    SysBusDevice parent_obj;
    CharBackend chr;
    QEMUTimer *timer;
    bool configured;
    bool started; /* the first stop (time 0) is armed */
    uint8_t n_motors;
    RigStm32TimerState *motor_timer[LINK_MOTORS];
    uint8_t motor_output[LINK_MOTORS];
    uint64_t motor_latches[LINK_MOTORS]; /* the timer's latches at the last stop */
    LinkUart uarts[LINK_UARTS];
    uint8_t ahead[LINK_MAX_PAYLOAD]; /* the bytes the session gave ahead of the master's reads */
    uint32_t ahead_at, ahead_len;
    uint8_t taken[LINK_READS * 8]; /* the times (u64) of the bytes taken from ahead, not yet told */
    uint32_t n_taken;
    qemu_irq pin_out[LINK_PIN_LINES]; /* each pin's outside driver (the GPIO port's input) */
    LinkPin pins[LINK_PIN_QUEUES];
    uint8_t out[LINK_OUT_BYTES]; /* messages not yet written */
    uint32_t out_len;
    uint8_t in[LINK_IN_BYTES]; /* bytes read from the session, from in_at to in_len not yet taken */
    uint32_t in_at, in_len;
};

static void G_NORETURN link_fail(const char *what)
{
    error_report("rig-link: %s", what);
    exit(1);
}

/* The lazy models' catch-ups (rig_link_sync_add), run before each "reached" */
#define LINK_SYNCS 32
static struct {
    void (*fn)(void *opaque);
    void *opaque;
} link_syncs[LINK_SYNCS];
static unsigned n_link_syncs;

void rig_link_sync_add(void (*sync)(void *opaque), void *opaque)
{
    if (n_link_syncs == LINK_SYNCS) {
        link_fail("more lazy models than the link can bring up to time");
    }
    link_syncs[n_link_syncs].fn = sync;
    link_syncs[n_link_syncs++].opaque = opaque;
}

static void link_flush(RigLinkState *s)
{
    if (s->out_len && qemu_chr_fe_write_all(&s->chr, s->out, (int)s->out_len) != (int)s->out_len) {
        link_fail("the session is gone (write)");
    }
    s->out_len = 0;
}

/* The link whose messages an exit still owes the session (the firmware's own exit: semihosting) */
static RigLinkState *link_at_exit;

static void link_flush_at_exit(void)
{
    RigLinkState *s = link_at_exit;
    link_at_exit = NULL;
    if (s && s->out_len) {
        qemu_chr_fe_write_all(&s->chr, s->out, (int)s->out_len); /* (a session gone: nothing to tell) */
    }
}

static void link_put(RigLinkState *s, uint8_t kind, const uint8_t *payload, uint32_t len)
{
    if (s->out_len + LINK_HEADER + len > sizeof s->out) {
        link_flush(s);
    }
    uint8_t *header = s->out + s->out_len;
    memset(header, 0, LINK_HEADER);
    header[0] = kind;
    stl_le_p(header + 4, len);
    if (len) {
        memcpy(header + LINK_HEADER, payload, len);
    }
    s->out_len += LINK_HEADER + len;
}

/* The times of the bytes read ahead that the master took, told before anything after them */
static void link_put_reads(RigLinkState *s)
{
    if (s->n_taken) {
        link_put(s, MSG_I2C_READS, s->taken, s->n_taken * 8);
        s->n_taken = 0;
    }
}

/* Every message goes after the reads taken before it, so the session sees the bus in order */
static void link_send(RigLinkState *s, uint8_t kind, const uint8_t *payload, uint32_t len)
{
    link_put_reads(s);
    link_put(s, kind, payload, len);
}

/* @len bytes from the session, blocking (after what is buffered is written: the session answers it) */
static void link_read(RigLinkState *s, uint8_t *to, uint32_t len)
{
    link_flush(s);
    Chardev *chr = qemu_chr_fe_get_driver(&s->chr);
    while (len) {
        if (s->in_at == s->in_len) {
            /* as much as has come, at least a byte (the socket chardev reads blocking here) */
            int got = CHARDEV_GET_CLASS(chr)->chr_sync_read(chr, s->in, sizeof s->in);
            if (got <= 0) {
                link_fail("the session is gone (read)");
            }
            s->in_at = 0;
            s->in_len = (uint32_t)got;
        }
        uint32_t n = MIN(len, s->in_len - s->in_at);
        memcpy(to, s->in + s->in_at, n);
        s->in_at += n;
        to += n;
        len -= n;
    }
}

/* The next message: its kind, its payload in @payload (its length in *len, checked to be within @max) */
static uint8_t link_receive(RigLinkState *s, uint8_t *payload, uint32_t max, uint32_t *len)
{
    uint8_t header[LINK_HEADER];
    link_read(s, header, LINK_HEADER);
    *len = ldl_le_p(header + 4);
    if (header[1] || header[2] || header[3] || *len > max) {
        link_fail("a malformed message from the session");
    }
    link_read(s, payload, *len);
    return header[0];
}

static void link_configure(RigLinkState *s, const uint8_t *p, uint32_t len)
{
    if (len < 1 || p[0] > LINK_MOTORS || len != 1u + 2u * p[0]) {
        link_fail("CONFIG: a bad motor list");
    }
    for (unsigned i = 0; i < p[0]; i++) {
        unsigned timer = p[1 + 2 * i], output = p[2 + 2 * i];
        g_autofree char *path = g_strdup_printf("/machine/tim%u", timer);
        Object *tim = timer >= 1 && timer <= 14 ? object_resolve_path_type(path, TYPE_RIG_STM32_TIMER, NULL) : NULL;
        if (tim == NULL || output >= RIG_TIM_OUTPUTS) {
            link_fail("CONFIG: no such timer output");
        }
        s->motor_timer[i] = RIG_STM32_TIMER(tim);
        s->motor_output[i] = (uint8_t)output;
    }
    s->n_motors = p[0];
    s->configured = true;
    for (unsigned n = 1; n <= LINK_UARTS; n++) { /* (the machine makes its USARTs after the link) */
        g_autofree char *path = g_strdup_printf("/machine/usart%u", n);
        Object *usart = object_resolve_path(path, NULL);
        s->uarts[n - 1].usart = usart ? DEVICE(usart) : NULL;
    }
}

/* The bytes' frames onto the USART's RX line, one after another from now or the end of those before */
static void link_uart_receive(RigLinkState *s, const uint8_t *p, uint32_t len)
{
    unsigned n = len >= UART_RX_HEADER ? p[0] : 0;
    LinkUart *u = n >= 1 && n <= LINK_UARTS ? &s->uarts[n - 1] : NULL;
    if (u == NULL || u->usart == NULL || p[1] || p[2] || p[3] || p[14] || p[15]) {
        link_fail("UART: no such USART, or a malformed frame description");
    }
    uint32_t frame_ns = ldl_le_p(p + 4), baud = ldl_le_p(p + 8);
    char parity = (char)p[12];
    uint8_t stop_bits = p[13];
    if (frame_ns == 0 || baud == 0 || (parity != 'N' && parity != 'E' && parity != 'O') ||
        (stop_bits != 1 && stop_bits != 2)) {
        link_fail("UART: a bad frame time, baud, parity or stop bits");
    }
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    int64_t t = u->busy_until_ns > now ? u->busy_until_ns : now;
    for (uint32_t i = UART_RX_HEADER; i < len; i++) {
        if (!rig_stm32_usart_receive(u->usart, p[i], t, baud, parity, stop_bits)) {
            link_fail("UART: more than 4096 bytes waiting for a USART");
        }
        t += frame_ns;
    }
    u->busy_until_ns = t;
}

/* The head edge onto its pin at its time, and the next one's time armed */
static void link_pin_deliver(void *opaque)
{
    LinkPin *q = opaque;
    int64_t now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    while (q->len && q->at_ns[q->head] <= now) {
        qemu_set_irq(q->link->pin_out[q->line], q->level[q->head]);
        q->head = (q->head + 1) % LINK_PIN_EDGES;
        q->len--;
    }
    if (q->len) {
        timer_mod(q->timer, q->at_ns[q->head]);
    }
}

static void link_pin_receive(RigLinkState *s, const uint8_t *p, uint32_t len)
{
    if (len < 4 || (len - 4) % LINK_EDGE || p[0] >= RIG_GPIO_PORTS || p[1] >= RIG_GPIO_PINS || p[2] || p[3]) {
        link_fail("PIN: a malformed pin or edge list");
    }
    int line = p[0] * RIG_GPIO_PINS + p[1];
    if (s->pin_out[line] == NULL) {
        link_fail("PIN: the chip has no such pin");
    }
    LinkPin *q = NULL;
    for (unsigned i = 0; i < LINK_PIN_QUEUES && q == NULL; i++) {
        if (s->pins[i].line == line) {
            q = &s->pins[i];
        }
    }
    for (unsigned i = 0; i < LINK_PIN_QUEUES && q == NULL; i++) {
        if (s->pins[i].line < 0) {
            q = &s->pins[i];
            q->line = line;
        }
    }
    uint32_t n = (len - 4) / LINK_EDGE;
    if (q == NULL || q->len + n > LINK_PIN_EDGES) {
        link_fail("PIN: more than 9 pins driven or more than 1024 edges waiting on one");
    }
    /* an edge the session dated before now (or before the last queued) happens then: time never goes back */
    int64_t t = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
    if (q->len) {
        t = MAX(t, q->at_ns[(q->head + q->len - 1) % LINK_PIN_EDGES]);
    }
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *e = p + 4 + i * LINK_EDGE;
        uint64_t at = ldq_le_p(e);
        if (e[8] > 1 || at > INT64_MAX) {
            link_fail("PIN: a level other than 0 or 1, or a time past the end of time");
        }
        t = MAX(t, (int64_t)at);
        uint32_t slot = (q->head + q->len++) % LINK_PIN_EDGES;
        q->at_ns[slot] = t;
        q->level[slot] = e[8];
    }
    if (q->len) {
        timer_mod(q->timer, q->at_ns[q->head]);
    }
}

/* An ADC input's volts from now on (a battery through its divider) */
static void link_adc_input(const uint8_t *p, uint32_t len)
{
    Object *adc = object_resolve_path("/machine/adc", NULL);
    if (len != 8 || p[2] || p[3] || adc == NULL || !rig_stm32_adc_set_input(DEVICE(adc), p[0], p[1], ldl_le_p(p + 4))) {
        link_fail("ADC: no such ADC or input, or a malformed message");
    }
}

/* What the firmware sent on each USART since the last stop */
static void link_uart_send_sent(RigLinkState *s)
{
    for (unsigned n = 1; n <= LINK_UARTS; n++) {
        if (s->uarts[n - 1].chr == NULL || s->uarts[n - 1].usart == NULL) {
            continue;
        }
        g_autofree char *id = g_strdup_printf("rig-usart%u", n);
        for (;;) {
            g_autofree char *text = qmp_ringbuf_read(id, LINK_UART_CHUNK, true, DATA_FORMAT_BASE64, &error_abort);
            gsize got = 0;
            g_autofree guchar *bytes = g_base64_decode(text, &got);
            if (got == 0) {
                break;
            }
            uint8_t p[1 + LINK_UART_CHUNK];
            p[0] = (uint8_t)n;
            memcpy(p + 1, bytes, MIN(got, LINK_UART_CHUNK));
            link_send(s, MSG_UART_SENT, p, 1 + (uint32_t)MIN(got, LINK_UART_CHUNK));
        }
    }
}

/* The flash's bytes the session asks for, read as the core reads them */
static void link_memory(RigLinkState *s, const uint8_t *p)
{
    uint32_t address = ldl_le_p(p), len = ldl_le_p(p + 4);
    uint8_t bytes[LINK_MAX_PAYLOAD];
    if (len > sizeof bytes || address < FLASH_BASE || address - FLASH_BASE > RIG_FLASH_BYTES - len) {
        link_fail("MEMORY: not within the flash, or more than 1024 bytes");
    }
    address_space_read(first_cpu->as, address, MEMTXATTRS_UNSPECIFIED, bytes, len);
    link_send(s, MSG_MEMORY, bytes, len);
}

/* Commands until a GO to a time after now (then armed) */
static void link_wait_command(RigLinkState *s)
{
    uint8_t p[LINK_MAX_PAYLOAD];
    for (;;) {
        uint32_t len;
        uint8_t kind = link_receive(s, p, sizeof p, &len);
        if (kind == MSG_CONFIG) {
            link_configure(s, p, len);
        } else if (kind == MSG_UART_RX) {
            link_uart_receive(s, p, len);
        } else if (kind == MSG_PIN_DRIVE) {
            link_pin_receive(s, p, len);
        } else if (kind == MSG_ADC_INPUT) {
            link_adc_input(p, len);
        } else if (kind == MSG_GO && len == 8 && s->configured) {
            int64_t t = (int64_t)ldq_le_p(p), now = qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
            timer_mod(s->timer, t > now ? t : now);
            return;
        } else if (kind == MSG_MEMORY && len == 8) {
            link_memory(s, p);
        } else if (kind == MSG_QUIT && len == 0) {
            exit(0);
        } else {
            link_fail("an unexpected command from the session");
        }
    }
}

/* The CPU's state: the exception being handled (IPSR), pc, CFSR, HFSR (16 bytes at @p) */
static void link_put_cpu(uint8_t *p)
{
    CPUARMState *env = &ARM_CPU(first_cpu)->env;
    stl_le_p(p, env->v7m.exception);
    stl_le_p(p + 4, env->regs[15]);
    stl_le_p(p + 8, env->v7m.cfsr[M_REG_NS]);
    stl_le_p(p + 12, env->v7m.hfsr);
}

/* A system reset (a handler of QEMU's reset, registered before the CPU's, so the CPU's state is still the
 * one the reset came on): its cause and that state to the session; the power-on reset is not told */
static void link_system_reset(void *opaque)
{
    RigLinkState *s = opaque;
    if (!s->started) {
        return;
    }
    uint8_t p[28];
    stq_le_p(p, (uint64_t)qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL));
    stl_le_p(p + 8, rig_reset_cause);
    link_put_cpu(p + 12);
    link_send(s, MSG_RESET, p, sizeof p);
    if (rig_reset_cause != RIG_RESET_SYSTEM) {
        /* A watchdog's reset ends the run there (the session reports it as a crash at this instant): the
         * chip goes no further, so nothing of the next boot (its output, its exit) can reach the run,
         * however far before the next stop the reset came. Waits for the session to close the link. */
        uint8_t none[1];
        uint32_t len;
        link_receive(s, none, 0, &len);
        link_fail("a message after a watchdog's reset");
    }
}

static void link_reached(void *opaque)
{
    RigLinkState *s = opaque;
    if (!s->configured) { /* the first stop: the session's CONFIG answers the HELLO */
        uint8_t config[LINK_MAX_PAYLOAD];
        uint32_t len;
        if (link_receive(s, config, sizeof config, &len) != MSG_CONFIG) {
            link_fail("the session's first message is not a CONFIG");
        }
        link_configure(s, config, len);
    }
    /* The stop holds the earliest deadline while it lasts: with the core asleep, a model arming its timer
     * here (a lazy model catching up) makes QEMU warp virtual time at once to the earliest deadline
     * (timerlist_rearm, icount_start_warp_timer), which without this would be that model's, past the
     * next stop the session is about to ask for. The GO re-arms the stop's timer. */
    timer_mod(s->timer, qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL));
    for (unsigned i = 0; i < n_link_syncs; i++) {
        link_syncs[i].fn(link_syncs[i].opaque);
    }
    uint8_t p[25 + LINK_MOTORS * 20];
    stq_le_p(p, (uint64_t)qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL));
    link_put_cpu(p + 8);
    p[24] = s->n_motors;
    uint32_t len = 25;
    for (unsigned i = 0; i < s->n_motors; i++) {
        /* (what the timer's read-only properties give, read in place: a lookup by name, a visitor each,
         * five per motor at every stop, is more than the stop needs) */
        const RigStm32TimerState *tim = s->motor_timer[i];
        uint64_t high = tim->pulse_ticks[s->motor_output[i]], hz = tim->latched_hz, latches = tim->latches;
        stl_le_p(p + len, hz ? (uint32_t)MIN(muldiv64(high, NANOSECONDS_PER_SECOND, hz), UINT32_MAX) : 0);
        stl_le_p(p + len + 4,
                 hz ? (uint32_t)MIN(muldiv64(tim->period_ticks, NANOSECONDS_PER_SECOND, hz), UINT32_MAX) : 0);
        stl_le_p(p + len + 8, (uint32_t)MIN(latches - s->motor_latches[i], UINT32_MAX));
        stq_le_p(p + len + 12, tim->latched_ns);
        s->motor_latches[i] = latches;
        len += 20;
    }
    link_uart_send_sent(s);
    link_send(s, MSG_REACHED, p, len);
    link_wait_command(s);
}

/* A reply of @kind with 1 to LINK_MAX_PAYLOAD bytes: the first is returned, the rest are the bytes ahead */
static uint8_t link_expect_ahead(RigLinkState *s, uint8_t kind)
{
    uint32_t len;
    if (link_receive(s, s->ahead, sizeof s->ahead, &len) != kind || len == 0) {
        link_fail("an unexpected reply from the session");
    }
    s->ahead_at = 1;
    s->ahead_len = len - 1;
    return s->ahead[0];
}

bool rig_link_i2c_start(RigLinkState *s, uint64_t t_ns, uint8_t address, bool read)
{
    uint8_t p[10];
    stq_le_p(p, t_ns);
    p[8] = address;
    p[9] = read;
    s->ahead_len = 0; /* what the last transfer did not read is dropped (the session knows) */
    link_send(s, MSG_I2C_START, p, sizeof p);
    uint8_t ack = link_expect_ahead(s, MSG_ACK);
    if (!read || !ack) {
        s->ahead_len = 0;
    }
    return ack != 0;
}

/* A bus event at the virtual time now, with @len bytes of @extra after the time */
static void link_send_event(RigLinkState *s, uint8_t kind, const uint8_t *extra, uint32_t len)
{
    uint8_t p[9];
    stq_le_p(p, (uint64_t)rig_i2c_now_ns());
    memcpy(p + 8, extra, len);
    link_send(s, kind, p, 8 + len);
}

void rig_link_i2c_write(RigLinkState *s, uint8_t byte) { link_send_event(s, MSG_I2C_WRITE, &byte, 1); }

uint8_t rig_link_i2c_read(RigLinkState *s)
{
    if (s->ahead_len == 0) {
        link_send_event(s, MSG_I2C_READ, NULL, 0);
        return link_expect_ahead(s, MSG_BYTE);
    }
    if (s->n_taken == LINK_READS) {
        link_put_reads(s);
    }
    stq_le_p(s->taken + 8 * s->n_taken++, (uint64_t)rig_i2c_now_ns());
    s->ahead_len--;
    return s->ahead[s->ahead_at++];
}

void rig_link_i2c_nack(RigLinkState *s) { link_send_event(s, MSG_I2C_NACK, NULL, 0); }

void rig_link_i2c_stop(RigLinkState *s)
{
    s->ahead_len = 0;
    link_send_event(s, MSG_I2C_STOP, NULL, 0);
}

static void link_realize(DeviceState *dev, Error **errp)
{
    RigLinkState *s = RIG_LINK(dev);
    if (!qemu_chr_fe_backend_connected(&s->chr)) {
        error_setg(errp, "rig-link: no chardev");
        return;
    }
    s->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, link_reached, s);
    for (unsigned n = 1; n <= LINK_UARTS; n++) {
        g_autofree char *id = g_strdup_printf("rig-usart%u", n);
        s->uarts[n - 1].chr = qemu_chr_find(id);
    }
    qemu_register_reset(link_system_reset, s);
    for (unsigned i = 0; i < LINK_PIN_QUEUES; i++) {
        LinkPin *q = &s->pins[i];
        q->link = s;
        q->line = -1;
        q->timer = timer_new_ns(QEMU_CLOCK_VIRTUAL, link_pin_deliver, q);
    }
    link_at_exit = s;
    atexit(link_flush_at_exit);
    uint8_t hello[2];
    stw_le_p(hello, LINK_VERSION);
    link_send(s, MSG_HELLO, hello, sizeof hello);
}

/* The first stop is at time 0, before the firmware's first instruction (a reset the firmware asks for
 * later changes nothing: the session's stop stays armed) */
static void link_reset(DeviceState *dev)
{
    RigLinkState *s = RIG_LINK(dev);
    if (!s->started) {
        s->started = true;
        timer_mod(s->timer, 0);
    }
}

static void link_init(Object *obj)
{
    RigLinkState *s = RIG_LINK(obj);
    qdev_init_gpio_out_named(DEVICE(obj), s->pin_out, "pin", LINK_PIN_LINES);
}

static Property link_properties[] = {
    DEFINE_PROP_CHR("chardev", RigLinkState, chr),
    DEFINE_PROP_END_OF_LIST(),
};

static void link_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->realize = link_realize;
    dc->reset = link_reset;
    device_class_set_props(dc, link_properties);
}

static const TypeInfo link_info = {
    .name = TYPE_RIG_LINK,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigLinkState),
    .instance_init = link_init,
    .class_init = link_class_init,
};

static void link_register_types(void) { type_register_static(&link_info); }

type_init(link_register_types)
