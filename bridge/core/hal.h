/* The bridge's hardware abstraction (docs/design.md §8): what a port (the STM32G431 firmware, the
   Linux process build/vbridge, the core's test tool) gives the core, and, listed below, what the port
   calls in the core. The core is portable C99: no heap, no OS, no MCU headers; it never blocks and
   never calls the port from anything but the calls the port made into it.

   The port gives (struct bridge_hal, function pointers with one context pointer, so a test can run
   several bridges in one process):
     now_us          the free-running microsecond clock (64 bits: it never wraps in practice)
     i2c_addr_enable the target address `addr` answers (on = 1) or not; the core turns 0x1E on only
                     while the emulated MPU-6050 has its bypass on (topology GY-86)
     link_tx         bytes to the host (a whole frame per call); the port queues what it can and drops
                     the rest (the host counts the gap in the sequence numbers); never blocks
     sbus_tx         one 25-byte SBUS frame for the board's RC input (100000 baud, 8E2, inverted on an
                     MCU); returns the bytes taken: fewer are dropped and counted by the core
     can_tx          optional (NULL: no CAN): one classic CAN frame, returns 0 when queued
     i2c_preload     optional (NULL: the port stretches SCL and fills its transmit register when
                     bridge_i2c_read is due): a target that does not stretch SCL (NOSTRETCH) sends a
                     read's first byte as the address is acknowledged, so it must hold it before; the
                     core gives it here, for target port 0 (the MPU-6050's and the MS5611's addresses)
                     or 1 (the HMC5883L's), whenever the chips' state may have changed. The port
                     returns 0, keeping what it holds, while that target is sending or its address
                     has just matched
     lock / unlock   optional (NULL: a port with no interrupts): keep the I2C events out while the
                     core touches what they share (the chips, the counters, the frames queued up);
                     lock returns what unlock restores, so they nest. The core holds the lock for
                     copies, counters, the sample instants and the preloads only: it decodes, frames
                     and encodes with it released, so an I2C event is never held off longer than that
                     (docs/bridge-firmware.md has the numbers)

   The port calls (bridge.h):
     bridge_i2c_start / bridge_i2c_write / bridge_i2c_read / bridge_i2c_stop
                     the I2C target events of the board's bus, stamped with their time in ns: a START
                     (or repeated START) with the address and direction (returns 1 to ACK), each byte the
                     board writes (returns 1 to ACK), each byte it reads, the STOP. With i2c_preload a
                     read's START takes its first byte itself (it is the one preloaded): the port asks
                     bridge_i2c_read from the second byte on
     bridge_i2c_unread / bridge_i2c_preload_all
                     the byte read ahead was never sent (the master's NACK); then the port's transmit
                     registers are free again
     bridge_capture_edge
                     an edge on an ESC input: channel, level after the edge, the capture timer's count
                     (it wraps: 16 or 32 bits, as configured) and the time in us
     bridge_link_rx  bytes from the host, in any chunking
     bridge_poll     often (every 100 us or so, and after each I2C transaction): sample instants,
                     SBUS frames due, PULSES and STATUS queued up, the host-silent rule
     bridge_idle     as often as it can: the samples encoded ahead of their instants, and the frames
                     queued up (by any call) framed and given to link_tx
   The I2C events may come from an interrupt; every other call comes from one main loop, with
   interrupts enabled (the core takes the port's lock where it must). */
#ifndef BRIDGE_HAL_H
#define BRIDGE_HAL_H

#include <stddef.h>
#include <stdint.h>

struct bridge_hal {
    void *ctx;
    uint64_t (*now_us)(void *ctx);
    void (*i2c_addr_enable)(void *ctx, uint8_t addr, int on);
    void (*link_tx)(void *ctx, const uint8_t *bytes, size_t n);
    size_t (*sbus_tx)(void *ctx, const uint8_t *frame, size_t n);
    int (*can_tx)(void *ctx, uint32_t id, const uint8_t *data, uint8_t len); /* NULL: no CAN */
    int (*i2c_preload)(void *ctx, unsigned port, uint8_t byte);              /* NULL: it stretches */
    uint32_t (*lock)(void *ctx);                                             /* NULL: no interrupts */
    void (*unlock)(void *ctx, uint32_t saved);
};

#endif
