/* The MCU tier's engine glue: simavr 1.6 (Debian's libsimavr) runs the AVR; this code is what the rig adds
 * around it (docs/mcu.md): the run loop to a target cycle with crash, sleep, watchdog and hang detection; a
 * TWI master of our own wired to the chip core in demand mode; motor pulses from the timers' registers as
 * the hardware latches them (or from pin edges); bytes into the USARTs at frame timing; pin schedules.
 *
 * Time is the MCU's cycle counter. Everything the glue schedules is a glue event, checked between two
 * instructions by the run loop (never inside simavr's cycle timers, which a reset clears): an event that
 * must stop the engine (a sample the chip core lacks) stops it there, and the next run resumes it before
 * the MCU runs another instruction, so a need served changes nothing the firmware can see.
 */
#ifndef RIG_MCU_GLUE_H
#define RIG_MCU_GLUE_H

#include <stdbool.h>
#include <stdint.h>

#include <simavr/sim_avr.h>

#include "chip_core.h"

#define MCU_API __attribute__((visibility("default")))

/* mcu_run's results (engine.py STOPS) */
#define MCU_REACHED 0
#define MCU_NEED 1
#define MCU_CRASHED 2
#define MCU_SLEEPING 3
#define MCU_WATCHDOG 4
#define MCU_HUNG 5
#define MCU_UNANSWERED 6

#define MCU_NEVER UINT64_MAX
#define MCU_MOTORS 8
#define MCU_PULSES 256 /* pulses kept per motor between two takes (the oldest are dropped) */
#define MCU_UARTS 4
#define MCU_RX_BYTES 4096
#define MCU_TX_BYTES 4096
#define MCU_PIN_EDGES 4096
/* input pins the rig drives at once: a parallel PWM receiver's 8 channels, and one more */
#define MCU_DRIVEN_PINS 9
#define MCU_TWI_EVENTS 96

typedef struct mcu_engine mcu_engine;
typedef struct mcu_poll mcu_poll;

/* the chip core's byte-level entry points, taken from the rig's library (one copy of the core) */
typedef struct {
    chip_need (*advance)(chip_board *b, uint64_t now_ns);
    bool (*start)(chip_board *b, uint64_t t_ns, uint8_t addr, bool read);
    void (*write_byte)(chip_board *b, uint8_t byte);
    uint8_t (*read_byte)(chip_board *b);
    void (*stop)(chip_board *b);
} mcu_chip_calls;

/* one record of a TWI transaction as the bus saw it */
typedef struct {
    uint64_t t_ns;
    uint8_t kind; /* 'S' start, 'A' address (value: SLA+R/W), 'W' byte written, 'R' byte read, 'P' stop */
    uint8_t value;
    uint8_t ack; /* address and W: acknowledged by the chip; R: acknowledged by the master */
    uint8_t pad[5];
} mcu_twi_record;

typedef struct {
    uint8_t state; /* TWI_* below */
    uint8_t event; /* the byte-level operation under way (EV_*), done at event_cycle */
    uint8_t sla;
    bool acked;       /* the chip of the last address answered */
    bool start_after; /* a STOP then a START */
    bool in_transfer; /* between a START and a STOP */
    uint64_t event_cycle;
    uint64_t start_ns;         /* the first START of the transfer: the chip core's time for all of it */
    uint64_t nack_since_cycle; /* first address NACK since the last ACK (MCU_NEVER: none) */
    uint32_t nacks_in_row;
    bool awaiting; /* an operation that ends in TWINT is under way or asked for */
    uint32_t transactions, bytes, nacks, collisions;
    /* what the firmware saw go wrong, beyond address NACKs (nacks) and TWDR write collisions:
     * data bytes NACKed; TWCR writes asking for an operation the unit did not start (twi.c busy_write);
     * waits given up (TWEN cleared while an operation that ends in TWINT was under way); the statuses
     * 0x00 (bus error) and arbitration lost (0x38, 0x68, 0x78, 0xB0) */
    uint32_t data_nacks, ignored, abandoned, bus_errors, arbitration_lost;
    mcu_twi_record cur[MCU_TWI_EVENTS], last[MCU_TWI_EVENTS];
    uint16_t n_cur, n_last;
    bool log_on;
    mcu_twi_record *log; /* every event, when log_on (the replayer test) */
    uint32_t n_log, cap_log;
} mcu_twi;

typedef struct {
    uint64_t rise, width, period; /* cycles */
} mcu_pulse;

typedef struct {
    mcu_engine *engine;
    int8_t timer;      /* -1: from the pin's edges */
    uint8_t channel;   /* 0 A, 1 B, 2 C */
    uint8_t port, bit; /* 'A'.. and 0..7 */
    uint16_t ddr;      /* data-space address of the pin's DDR */
    bool has_pending;
    mcu_pulse pending; /* computed from the registers, not yet ended */
    uint16_t ocr_prev; /* phase and frequency correct: the compare value latched at the last BOTTOM */
    bool has_prev;
    uint64_t edge_rise, edge_prev_rise; /* pin edges (MCU_NEVER: none) */
    mcu_pulse out[MCU_PULSES];
    uint16_t n_out;
    uint32_t dropped;
    uint32_t from_timer, from_edges; /* pulses measured each way (pwm.c) */
} mcu_motor;

typedef struct {
    bool used;
    uint8_t n;
    uint16_t tccra, tccrb, tcnt, icr, ocr[3];
    bool wide; /* 16-bit */
    uint8_t mode, cs;
    uint8_t phase; /* the next event is a BOTTOM (0) or a TOP (1) */
    uint64_t next;
    uint64_t anchor;
    uint64_t events;
} mcu_timer;

/* a register write handler of simavr's, wrapped: the glue hears the write, then simavr does its part */
typedef struct {
    mcu_engine *engine;
    mcu_timer *timer;
    avr_io_write_t c;
    void *param;
} mcu_wrap;

typedef struct {
    bool used;
    mcu_engine *engine;
    uint16_t base; /* UCSRnA's data-space address: B, C, UBRRL, UBRRH, UDR follow at +1, +2, +4, +5, +6 */
    void *irq;     /* simavr's UART_IRQ_INPUT */
    void *port;    /* simavr's avr_uart_t */
    avr_io_write_t orig[6];
    void *orig_param[6];
    uint8_t bytes[MCU_RX_BYTES];
    uint32_t head, len;
    uint64_t next;         /* cycle the next byte's stop bit ends */
    uint64_t frame_cycles; /* one frame, in cycles */
    uint32_t baud;
    uint8_t parity, stop_bits; /* 'N' 'E' 'O' */
    uint32_t delivered, frame_errors;
    uint32_t receiver_off; /* bytes that arrived while RXEN was clear: lost, as on the hardware */
    uint8_t tx[MCU_TX_BYTES];
    uint32_t n_tx;
    uint32_t tx_dropped;
} mcu_uart;

typedef struct {
    uint64_t cycle;
    uint8_t level;
} mcu_edge;

/* a pin of the ATmega2560's ports J and K, whose pin change interrupts simavr 1.6 lacks */
typedef struct {
    mcu_engine *engine;
    uint8_t group; /* PCINT group 1 (port J) or 2 (port K) */
    uint8_t mask;  /* its bit in PCMSKn */
} mcu_pcint_pin;

typedef struct {
    bool used;
    uint8_t port, bit;
    mcu_edge edges[MCU_PIN_EDGES];
    uint32_t head, len;
} mcu_pin;

/* an output pin watched for the hang check (any change while its DDR bit is set is activity) */
typedef struct {
    mcu_engine *engine;
    uint16_t ddr;
    uint8_t bit;
} mcu_watched_pin;

struct mcu_engine {
    avr_t *avr;
    uint32_t clock_hz;
    uint32_t code_end; /* bytes of the image: a PC at or past it runs erased flash */
    uint64_t next_event;
    uint64_t target, stop_at; /* the run's target cycle; where it looks at the deadlines next */
    /* the stop */
    int stop;
    uint32_t stop_pc;
    uint64_t stop_cycle;
    char what[200];
    bool bad_opcode;
    uint32_t bad_pc;
    char last_error[200];
    /* resets */
    void (*core_reset)(avr_t *avr);
    bool reset_seen;
    bool stock_extint;
    bool wdton; /* the WDTON fuse: simavr's WDTCSR handler, wrapped */
    avr_io_write_t wdt_write;
    void *wdt_param;
    uint32_t resets, watchdog_resets, watchdog_limit;
    uint64_t marker; /* the cycle simavr's sleep may not pass */
    /* hang: no TWI, no motor pulse, no USART byte sent and no output pin changed for hang_cycles */
    uint64_t hang_cycles, last_activity;
    mcu_watched_pin watched[11 * 8];
    uint8_t n_watched;
    uint64_t unanswered_cycles;
    uint64_t instructions;
    /* the chip core */
    chip_board *board;
    mcu_chip_calls chip;
    chip_need need;
    mcu_twi twi;
    avr_int_vector_t *twi_vector;
    mcu_motor motors[MCU_MOTORS];
    uint8_t n_motors;
    mcu_timer timers[6];
    mcu_wrap wraps[12];
    uint8_t n_wraps;
    mcu_uart uarts[MCU_UARTS];
    mcu_pin pins[MCU_DRIVEN_PINS];
    avr_int_vector_t pcint[3]; /* [1] PCINT1, [2] PCINT2 (2560) */
    mcu_pcint_pin pcint_pins[15];
    struct mcu_timer_wraps *timer_wraps; /* timer_modes.c */
    mcu_poll *poll;                      /* the polling-loop skip (polling.c; NULL: off) */
    bool poll_watch;                     /* it follows every instruction (a loop recorded or checked) */
};

/* glue.c */
uint64_t mcu_ns(const mcu_engine *e, uint64_t cycle);
void mcu_reschedule(mcu_engine *e);
void mcu_deadline(mcu_engine *e);
/* twi.c */
void mcu_twi_attach(mcu_engine *e);
void mcu_twi_reset(mcu_engine *e);
int mcu_twi_event(mcu_engine *e);
/* pwm.c */
bool mcu_pwm_attach(mcu_engine *e, mcu_motor *m);
void mcu_pwm_reset(mcu_engine *e);
void mcu_pwm_event(mcu_engine *e);
uint64_t mcu_pwm_next(const mcu_engine *e);
/* serial.c */
void mcu_serial_event(mcu_engine *e);
uint64_t mcu_serial_next(const mcu_engine *e);
void mcu_pcint_attach(mcu_engine *e);
/* timer_modes.c */
void mcu_timer_modes_attach(mcu_engine *e);
void mcu_timer_modes_stock(mcu_engine *e, bool stock);
/* polling.c */
void mcu_poll_step(mcu_engine *e, uint32_t pc_before);
void mcu_poll_free(mcu_engine *e);

#endif
