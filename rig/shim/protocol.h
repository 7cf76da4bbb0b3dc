/*
 * The wire protocol between the preloaded shim (rigshim.c, inside the DUT) and the session (Python,
 * rig/protocol.py mirrors these numbers and a test checks that the two agree).
 *
 * Transport: one Unix stream socket connection per DUT process. Every message is a 16-byte header
 * and `len` bytes of payload, little-endian. Requests that need an answer (HELLO, I2C, WAIT) get
 * exactly one reply of the same type; notices (PWM, NOTE, I2C_WRITE, STALL) get none, so they cost the DUT no round
 * trip. Clock reads cost no message at all: the session publishes sim time in a shared page. In
 * lockstep a connection's messages after HELLO may go through a mailbox in shared memory instead
 * (ring.h): the same bytes, through two byte rings and a futex.
 */
#ifndef RIG_PROTOCOL_H
#define RIG_PROTOCOL_H

#include <stdint.h>

#define RIG_PROTOCOL_VERSION 5u
#define RIG_MAX_PAYLOAD 65536u

struct rig_hdr {
    uint32_t len;    /* payload bytes after the header */
    uint16_t type;   /* RIG_MSG_* */
    uint16_t status; /* replies: 0 or a positive errno */
    uint64_t t_ns;   /* requests: the DUT's sim time; replies: sim time after the request */
};

enum {
    RIG_MSG_HELLO = 1, /* payload: u32 version, u32 pid[, u32 RIG_HELLO_MAILBOX]. Reply: status; when the
                          session grants the mailbox asked for, payload u32 RIG_HELLO_MAILBOX and the
                          mailbox's memfd (SCM_RIGHTS) */
    RIG_MSG_I2C = 2,   /* payload: u16 bus, u16 nmsgs, nmsgs x rig_i2c_msg, then the write bytes.
                          Reply: status; payload: the bytes of each read message in order (a
                          RECV_LEN read gives its count byte, then count bytes) */
    RIG_MSG_PWM = 3,   /* notice; payload: rig_pwm_msg */
    RIG_MSG_WAIT = 4,  /* payload: u64 wake_ns (RIG_WAIT_FOREVER: until an event), u32 kind, u32 0.
                          Reply: t_ns = the new time; payload u32 RIG_WAKE_*. Kind RIG_WAIT_AHEAD is
                          a notice (no reply): the shim has already moved the clock to wake_ns */
    RIG_MSG_NOTE = 5,  /* notice; payload: text the session reports (an unsupported call, say) */
    /* notice; payload as RIG_MSG_I2C: one write message of a byte or more to an address the session has
       promised acknowledges (rig_shm.acks). The shim has answered the DUT itself (success, no bus time);
       the session transfers it at its time, and a promise broken ends the run in an error. */
    RIG_MSG_I2C_WRITE = 6,
    /* notice; payload: text naming a DUT thread that spins (threads.c): it ran on past a second of
       virtual time without a wait the shim knows while another thread was due. The session ends the
       run as its stall watchdog does, with this text. */
    RIG_MSG_STALL = 7,
};

struct rig_i2c_msg {
    uint16_t addr;
    uint16_t flags; /* I2C_M_RD, I2C_M_RECV_LEN, I2C_M_TEN as in <linux/i2c.h> */
    uint16_t len;
    uint16_t reserved;
};

enum { RIG_PWM_EXPORT = 1, RIG_PWM_UNEXPORT, RIG_PWM_PERIOD, RIG_PWM_DUTY, RIG_PWM_ENABLE, RIG_PWM_POLARITY };

struct rig_pwm_msg {
    uint16_t chip;
    uint16_t channel;
    uint16_t attr; /* RIG_PWM_* */
    uint16_t reserved;
    uint64_t value; /* ns for period/duty; 0/1 for enable; 1 = inversed for polarity */
};

#define RIG_HELLO_MAILBOX 1u /* HELLO's third word: this process would take a mailbox (ring.h) */

#define RIG_WAIT_FOREVER UINT64_MAX
/* AHEAD: a sleep that nothing can cut short, so the shim moves the clock itself and tells the session
   in a notice; the session runs the world to wake_ns before it reads the next message. The DUT's first
   look at the outside world after it (a read, a poll, an ioctl outside i2c-dev) first asks for a
   plain WAIT to now, so the session has run everything due (SBUS bytes are in the pty) by then. */
enum { RIG_WAIT_SLEEP = 1, RIG_WAIT_POLL = 2, RIG_WAIT_AHEAD = 3 };
enum { RIG_WAKE_DEADLINE = 0, RIG_WAKE_EVENT = 1, RIG_WAKE_SLICE = 2 };

/* The shared page (a file the session creates; the shim maps it). */
#define RIG_SHM_MAGIC 0x31304d4853474952ull /* "RIGSHM01" */
#define RIG_PWM_MAX 16

struct rig_pwm_state {
    uint64_t period_ns;
    uint64_t duty_ns;
    uint32_t exported;
    uint32_t enabled;
    uint32_t inversed;
    uint32_t reserved;
};

/* A promise in the shared page: a transfer of one write message (a byte or more) to addr on bus that
   starts before until_ns is acknowledged. The session makes it for a chip that answers every write (no
   bus fault can silence it before until_ns) when transfers take no bus time; the shim then sends such a
   write as a notice (RIG_MSG_I2C_WRITE) and answers the DUT at once: a round trip fewer for each write
   that only starts something (the MS5611's conversions: 0.3 per FC cycle of the reference FC). */
#define RIG_ACK_MAX 4
struct rig_ack {
    uint16_t bus;
    uint16_t addr;
    uint32_t reserved;
    uint64_t until_ns;
};

/* Whether acks[RIG_ACK_MAX] promise a transfer of n messages, the first of flags and len to addr on bus,
   starting at t_ns: one plain write of a byte or more, to a promised address, before its promise ends.
   The shim asks before it answers a write itself; the session asks of every such notice it takes. */
static inline int rig_ack_promised(const struct rig_ack *acks, uint16_t bus, unsigned n, uint16_t addr, uint16_t flags,
                                   uint16_t len, uint64_t t_ns)
{
    if (n != 1 || flags || len == 0)
        return 0;
    for (int i = 0; i < RIG_ACK_MAX; i++)
        if (acks[i].bus == bus && acks[i].addr == addr && t_ns < acks[i].until_ns)
            return 1;
    return 0;
}

struct rig_shm {
    uint64_t magic;
    uint32_t version;
    uint32_t npwm;   /* channels of pwmchip0 */
    uint64_t sim_ns; /* lockstep: the one clock; the shim adds quantum_ns per clock read */
    uint64_t quantum_ns;
    uint64_t epoch_ns;     /* CLOCK_REALTIME at sim time 0 */
    uint64_t mono_base_ns; /* CLOCK_MONOTONIC at sim time 0 */
    struct rig_pwm_state pwm[RIG_PWM_MAX];
    uint64_t limit_ns;      /* lockstep: the run ends here (--duration or --sim-timeout); a clock read
                               that reaches it asks the session, which ends the run */
    uint32_t wake_seq;      /* mailboxes (ring.h): bumped by every message a DUT process puts in one;
                               the session sleeps on it (a futex) */
    uint32_t session_state; /* RIG_SESSION_*: how a process that put a message wakes the session */
    /* lockstep: the session's promises (an entry unused: until_ns 0) */
    struct rig_ack acks[RIG_ACK_MAX];
};
#define RIG_SHM_LIMIT_OFFSET 560 /* offsetof(struct rig_shm, limit_ns), for the Python side */
#define RIG_SHM_WAKE_OFFSET 568  /* offsetof(struct rig_shm, wake_seq) */
#define RIG_SHM_ACKS_OFFSET 576  /* offsetof(struct rig_shm, acks) */
/* POLL (0, the page's first state): in its loop's epoll, woken by a byte on the connection's socket;
   RUNNING: it looks at every mailbox before it sleeps; FUTEX: asleep on wake_seq */
enum { RIG_SESSION_POLL = 0, RIG_SESSION_RUNNING = 1, RIG_SESSION_FUTEX = 2 };

#endif
