/* The virtual bridge's parts (vbridge.c: set-up, the HAL and the loop; vbridge_board.c: the board side,
   its I2C transfers, PWM writes and shim connections): the state they share. */
#ifndef VBRIDGE_H
#define VBRIDGE_H

#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "bridge.h"
#include "protocol.h"

#define MAX_CONNS 32
#define BIT_NS 2500u /* 400 kHz */
#define TX_BUF 65536
#define I2C_M_RD 0x0001
#define I2C_M_TEN 0x0010
#define I2C_M_RECV_LEN 0x0400
#define I2C_SMBUS_BLOCK_MAX 32

struct conn {
    int fd;
    int hello;
    uint8_t *buf; /* header + payload being received */
    size_t have, need;
    /* a reply held until the transfer's end on the wall clock */
    int pending;
    uint64_t due_ns;
    uint8_t *reply;
    size_t reply_len;
};

struct pwm_ch {
    uint64_t period_ns, duty_ns;
    int exported, enabled, inversed;
    uint64_t next_rise_ns; /* 0: no pulses */
    uint64_t fall_ns;      /* the fall of the pulse under way (0: low) */
};

struct vbridge_state {
    struct bridge b;
    int link; /* the host link's pty master */
    int rc, rc_slave;
    int can; /* the CAN bus as an slcan adapter's pty (master) */
    uint64_t can_drain_ns;
    int listener;
    int host_seen; /* the host opened the link once */
    unsigned bus, npwm;
    struct conn conns[MAX_CONNS];
    struct pwm_ch pwm[RIG_PWM_MAX];
    uint8_t tx[TX_BUF];
    size_t tx_n;
    unsigned long tx_dropped;
};
extern struct vbridge_state v;

void pwm_edges(uint64_t now);
uint64_t pwm_next(void);
void drop(struct conn *c);
void on_readable(struct conn *c);
void send_due_replies(uint64_t now);
uint64_t mono_ns(void);

#endif
