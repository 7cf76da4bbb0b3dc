/*
 * The mailbox: a lockstep connection's messages through shared memory in place of its socket. The
 * shim (link.c) and the session (rig/lockstep/mailbox.c) both include this file: one layout, one
 * set of ring operations, for both sides.
 *
 * Why: in lockstep the session and the DUT take turns on one core, and every request is a round trip
 * on the run's critical path (two per FC cycle). Through the socket a round trip cost 14-16 us on one
 * core, through shared memory and a futex about 6 (bench/reference/roundtrip.md): the same two
 * context switches, without the socket's sends, receives and epoll.
 *
 * What: a memfd the session makes for a connection that asks in its HELLO (RIG_HELLO_MAILBOX) and
 * passes back with the HELLO reply. It holds two byte rings: up (the DUT's messages) and down (the
 * session's replies), each carrying exactly the bytes the socket would have. The socket stays: its
 * end is how each side learns the other is gone, and a byte on it wakes a session that waits in its
 * loop's epoll (rig_shm.session_state says how the session waits: protocol.h).
 *
 * Each counter is written by one side only: up.head and down.tail by the DUT, up.tail and down.head
 * by the session. A reader trusts nothing it reads: a head further than RIG_RING_SIZE from its own
 * tail is a broken ring, and the session drops that connection as it drops a malformed message.
 */
#ifndef RIG_RING_H
#define RIG_RING_H

#include <errno.h>
#include <linux/futex.h>
#include <stdint.h>
#include <string.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "protocol.h"

#define RIG_RING_SIZE (1u << 20)                /* a power of two, above any message and what a process holds */
#define RIG_MAILBOX_MAGIC 0x31584f424c49414dull /* "MAILBOX1" */

struct rig_ring_ctl {
    uint64_t head;     /* bytes ever written (the writer's) */
    uint64_t tail;     /* bytes ever read (the reader's) */
    uint32_t seq;      /* a futex word: bumped after each head; down's reader (the DUT) sleeps on it */
    uint32_t sleeping; /* down: the DUT sleeps on seq (the session wakes it) */
    uint8_t pad[40];   /* (a cache line each) */
};

struct rig_mailbox {
    uint64_t magic;
    uint64_t ring_size; /* RIG_RING_SIZE of the session's build (the shim checks it is its own) */
    uint8_t pad[48];
    struct rig_ring_ctl up, down;
    uint8_t up_data[RIG_RING_SIZE];
    uint8_t down_data[RIG_RING_SIZE];
};

/* The bytes readable from tail: -1 when the head is not one a ring can have. */
static inline int64_t ring_used(const struct rig_ring_ctl *c, uint64_t tail)
{
    uint64_t used = __atomic_load_n(&c->head, __ATOMIC_ACQUIRE) - tail;
    return used > RIG_RING_SIZE ? -1 : (int64_t)used;
}

/* The room to write at head: -1 when the reader's tail is not one a ring can have. */
static inline int64_t ring_room(const struct rig_ring_ctl *c, uint64_t head)
{
    uint64_t used = head - __atomic_load_n(&c->tail, __ATOMIC_ACQUIRE);
    return used > RIG_RING_SIZE ? -1 : (int64_t)(RIG_RING_SIZE - used);
}

/* n bytes at position at, across the ring's end */
static inline void ring_copy_in(uint8_t *data, uint64_t at, const void *from, size_t n)
{
    size_t i = (size_t)(at & (RIG_RING_SIZE - 1)), first = n < RIG_RING_SIZE - i ? n : RIG_RING_SIZE - i;
    memcpy(data + i, from, first);
    memcpy(data, (const uint8_t *)from + first, n - first);
}

static inline void ring_copy_out(const uint8_t *data, uint64_t at, void *to, size_t n)
{
    size_t i = (size_t)(at & (RIG_RING_SIZE - 1)), first = n < RIG_RING_SIZE - i ? n : RIG_RING_SIZE - i;
    memcpy(to, data + i, first);
    memcpy((uint8_t *)to + first, data, n - first);
}

/* Makes what was written up to head readable; a full barrier after it (the caller then reads whether
   the reader sleeps: the reader sets that before it looks at head again, so one of the two sees the
   other). */
static inline void ring_publish(struct rig_ring_ctl *c, uint64_t head)
{
    __atomic_store_n(&c->head, head, __ATOMIC_RELEASE);
    __atomic_fetch_add(&c->seq, 1, __ATOMIC_SEQ_CST);
}

/* FUTEX_WAIT on a shared word (not _PRIVATE: two processes); 0 or -1 with errno (EAGAIN: it moved,
   ETIMEDOUT, EINTR) */
static inline long rig_futex_wait(uint32_t *word, uint32_t seen, uint64_t timeout_ns)
{
    struct timespec ts = { (time_t)(timeout_ns / 1000000000u), (long)(timeout_ns % 1000000000u) };
    return syscall(SYS_futex, word, FUTEX_WAIT, seen, &ts, NULL, 0);
}

static inline void rig_futex_wake(uint32_t *word) { syscall(SYS_futex, word, FUTEX_WAKE, 1, NULL, NULL, 0); }

#endif
