/* The bridge core (docs/design.md §8): one chip board (the chip core), the link to the host, the ESC
   pulse capture and SBUS out, behind the HAL of hal.h. Portable C99: no heap, no OS, no MCU headers.

   Down (host -> bridge), each message acted on only once a HELLO of the bridge's protocol version was
   agreed (before that, and after a HELLO of another version, everything but HELLO is refused and
   counted): HELLO (HELLO_REPLY, the link counters start again), CONFIG (topology, addresses, SBUS
   period, capture channels, tracing; the chips reset), IMU/MAG/BARO samples (queued in the chip core
   with their valid time; one that arrives after its valid time is counted late), SBUS (channels and
   flags), TIME_SYNC (TIME_SYNC_REPLY with the times the probe arrived and the reply left), FAULT (a bus
   fault of the chip core), HEARTBEAT. A message whose values are out of range is refused and counted:
   nothing of it is applied. A frame that fails the link's checks is counted there (link.h).

   Up: REG_WRITE per register byte the board wrote (acknowledged), PULSES when new pulses came (at most
   every pulses_period_us, and every 100 ms anyway), STATUS every status_period_us and when the host
   falls silent or comes back, TRACE per transaction when CONFIG asks for it. Each is queued with its
   sequence number in the outbox (a copy: the I2C events send too) and framed by bridge_idle.

   Host silence: no good frame for BRIDGE_HOST_SILENT_US sets host_silent (STATUS says so at once); the
   chips hold their last samples and count an underrun at every sample instant without a new one, the
   board's transactions are answered as ever, SBUS frames carry frame-lost (and failsafe after
   SBUS_FAILSAFE_US). The next good frame clears it. */
#ifndef BRIDGE_BRIDGE_H
#define BRIDGE_BRIDGE_H

#include <stddef.h>
#include <stdint.h>

#include "chip_core.h"
#include "hal.h"
#include "link.h"
#include "pwm_capture.h"
#include "sbus_out.h"

#define BRIDGE_CORE_VERSION 1
#define BRIDGE_PULSES_EVERY_US 100000u
/* messages up queued for bridge_idle to frame: a burst of register writes at 1 MHz fills it no faster
   than the main loop frames them; one that finds it full is dropped (its sequence number is spent:
   the host counts the gap) */
#define BRIDGE_OUTBOX 32u
/* the target ports of hal.h's i2c_preload: 0 answers the MPU-6050 and the MS5611, 1 the HMC5883L */
#define BRIDGE_I2C_PORTS 2u
/* the longest a transaction left open (no STOP) holds the chips' time still */
#define BRIDGE_HOLD_NS 5000000u

struct bridge_cfg {
    char id[16]; /* the bridge's name in HELLO_REPLY */
    uint8_t fw_sha[8];
    uint32_t clock_hz;
    uint32_t status_period_us; /* 200000 */
    uint32_t pulses_period_us; /* 2000 */
    struct pwm_capture_cfg capture;
};

struct bridge_counters {
    uint32_t late_samples, refused, sbus_dropped, i2c_errors, i2c_acked;
    uint32_t can_dropped;      /* capture frames the port could not queue */
    uint32_t preload_misses;   /* reads whose preloaded first byte was not the chip's */
    uint32_t underrun_base[3]; /* the chip core's underrun counts at the last HELLO */
};

/* what a target port holds for the next read (i2c_preload) */
struct bridge_preload {
    uint8_t addr, byte, loaded;
    uint64_t t_ns; /* the chips' time it was taken at: a read that matches starts there */
};

struct bridge {
    struct bridge_hal hal;
    struct bridge_cfg cfg;
    chip_board board;
    struct link_rx rx;
    struct pwm_capture cap;
    struct sbus_out sbus;
    struct bridge_counters n;
    int agreed;  /* a HELLO of our version came */
    int offline; /* CONFIG is rebuilding the chip board: the I2C events leave it alone */
    uint8_t topology, mpu_addr, hmc_addr, baro_addr, capture_channels, trace;
    uint8_t tx_seq;
    struct bridge_msg outbox[BRIDGE_OUTBOX]; /* messages up, sequence numbers given, not yet framed */
    uint32_t out_head, out_tail;             /* (under the lock) */
    uint8_t enabled[4];                      /* by chip (CHIP_MPU..CHIP_BARO): its address is on in the port's target */
    uint64_t last_rx_us;
    int host_silent;
    uint64_t next_status_us, next_pulses_us;
    uint32_t pulses_sent;
    uint8_t can_seq; /* the CAN capture frames' sequence byte */
    /* the transaction under way */
    int cur_chip; /* CHIP_MPU, _HMC, _BARO; -1: none of ours */
    uint8_t cur_addr, cur_read, ptr;
    unsigned cur_bytes;
    uint8_t trace_data[16];
    uint8_t trace_len;
    uint64_t trace_t_ns;
    uint64_t txn_t_ns; /* the open transaction's first START: the poll holds the chips' time till its STOP */
    struct bridge_preload pre[BRIDGE_I2C_PORTS];
    uint8_t guess0;       /* the address port 0's next read is expected from: the last one it answered */
    uint32_t preload_gen; /* the chips' changes (sample instants...) when the ports were last preloaded */
};

struct bridge_cfg bridge_defaults(void);
void bridge_init(struct bridge *b, const struct bridge_hal *hal, const struct bridge_cfg *cfg);

/* the port's calls (hal.h) */
int bridge_i2c_start(struct bridge *b, uint64_t t_ns, uint8_t addr, int read);
int bridge_i2c_write(struct bridge *b, uint64_t t_ns, uint8_t byte);
uint8_t bridge_i2c_read(struct bridge *b, uint64_t t_ns);
/* the last byte bridge_i2c_read gave was never sent (the master NACKed the one before): the chip is
   as if it had not been read (a FIFO keeps the byte, a register pointer stays) */
void bridge_i2c_unread(struct bridge *b);
/* a port with i2c_preload: its transmit registers are free (after the master's NACK): each gets the
   first byte of the read it expects next */
void bridge_i2c_preload_all(struct bridge *b);
/* from the port's main loop, often, with interrupts enabled: encodes the queued samples ahead, so the
   I2C interrupt at a sample instant copies them instead of encoding (chip_prepare), then frames what
   is queued up (bridge_flush) */
void bridge_idle(struct bridge *b);
/* the messages queued up, framed and given to the port's link_tx, oldest first */
void bridge_flush(struct bridge *b);
void bridge_i2c_stop(struct bridge *b, uint64_t t_ns);
void bridge_capture_edge(struct bridge *b, unsigned channel, int level, uint32_t count, uint64_t t_us);
void bridge_link_rx(struct bridge *b, const uint8_t *bytes, size_t n);
void bridge_poll(struct bridge *b);

/* what STATUS reports now */
void bridge_status(struct bridge *b, struct bridge_status *out);
/* one message up (id and fields set; the sequence byte is the bridge's), queued: it goes out at the
   next bridge_flush. Callable from the I2C events: it only copies */
void bridge_send(struct bridge *b, struct bridge_msg *msg);

#endif
