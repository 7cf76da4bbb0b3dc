/*
 * The STM32F4's USART (rig_stm32_usart.c, the receiver in rig_stm32_usart_rx.c): the state both halves
 * share, the register bits and the line's timing.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#ifndef RIG_STM32_USART_H
#define RIG_STM32_USART_H

#include "chardev/char-fe.h"
#include "rig_stm32f4.h"

enum { R_SR, R_DR, R_BRR, R_CR1, R_CR2, R_CR3, R_GTPR, R_COUNT };

#define SR_PE (1u << 0)
#define SR_FE (1u << 1)
#define SR_NF (1u << 2)
#define SR_ORE (1u << 3)
#define SR_IDLE (1u << 4)
#define SR_RXNE (1u << 5)
#define SR_TC (1u << 6)
#define SR_TXE (1u << 7)
#define SR_LBD (1u << 8)
#define SR_CTS (1u << 9)
#define SR_READ_CLEARED (SR_PE | SR_FE | SR_NF | SR_ORE | SR_IDLE) /* by SR read then DR read */
#define CR1_SBK (1u << 0)
#define CR1_RE (1u << 2)
#define CR1_TE (1u << 3)
#define CR1_IDLEIE (1u << 4)
#define CR1_RXNEIE (1u << 5)
#define CR1_TCIE (1u << 6)
#define CR1_TXEIE (1u << 7)
#define CR1_PEIE (1u << 8)
#define CR1_PS (1u << 9)
#define CR1_PCE (1u << 10)
#define CR1_M (1u << 12)
#define CR1_UE (1u << 13)
#define CR1_OVER8 (1u << 15)
#define CR2_STOP_SHIFT 12
#define CR2_LBDIE (1u << 6)
#define CR3_EIE (1u << 0)
#define CR3_DMAR (1u << 6)
#define CR3_DMAT (1u << 7)
#define CR3_CTSIE (1u << 10)
#define CR3_ONEBIT (1u << 11)

#define NS 1000000000ull
#define SIXTEENTHS 16

#define DMA_CR_HTIE (1u << 3) /* RM0090 10.5.5, SxCR */
#define DMA_CR_TCIE (1u << 4)
#define DMA_CR_DIR_P2M (0u << 6)
#define DMA_CR_DIR_M2P (1u << 6)
#define DMA_CR_DIR_MASK (3u << 6)
#define DMA_CR_CIRC (1u << 8)
#define DMA_CR_DBM (1u << 18)

/* The line as the sender drives it: its frames, each from its start (start bit, data bits, parity,
 * stop bits at its baud); idle (high) between them */
typedef struct {
    int64_t start_ns;
    int64_t end_ns; /* the first whole ns past its last bit: start_ns + n_bits bits, rounded up */
    uint32_t baud;
    uint8_t n_bits;
    uint16_t bits; /* bit i: the level of the i-th bit on the wire */
} UsartFrame;
#define FRAMES RIG_USART_FRAMES

/* Where the receiver is on the line */
typedef struct {
    int64_t pos_ns;       /* it looks for a start bit from here */
    bool idle_armed;      /* a frame was received since the last IDLE (30.6.1: IDLE once per RXNE) */
    int64_t idle_from_ns; /* the end of that frame: IDLE a frame's time later if the line stays high */
} RigUsartRxCursor;

typedef struct RigStm32UsartState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    RigStm32DmaState *dma_ctl; /* property "dma": the controller its requests go to */
    CharBackend chr;
    uint8_t apb, rcc_bit; /* its bus (1, 2) and bit in RCC_APBxENR/APBxRSTR (properties "apb", "rcc-bit") */
    bool uart;            /* property "uart": UART4/UART5, without the synchronous and flow-control bits */
    uint8_t index;        /* property "index": n of USARTn (its DMA requests' numbers, the trace's name) */
    bool trace_bytes;     /* property "trace-bytes": each byte sent on stderr with its frame's end */
    const RigRegister *table;
    qemu_irq irq, dma[2]; /* "dma-rx", "dma-tx" */
    bool dma_level[2];
    bool catching_up; /* in catch_up(): the DMA's accesses it makes do not catch up again */
    QEMUTimer *timer;
    uint32_t regs[R_COUNT]; /* DR: the received data register (RDR) */
    uint32_t sr_seen;       /* SR as last read: the first half of the clear sequences */
    /* transmitter */
    uint16_t tdr;       /* the byte written to DR, waiting while TXE = 0 */
    bool tx_busy;       /* the shift register sends a frame, until tx_end_ns */
    bool tx_idle_frame; /* that frame is TE's idle frame (nothing to the chardev) */
    uint8_t tx_byte;    /* the byte it sends */
    int64_t tx_end_ns;
    /* receiver */
    UsartFrame frames[FRAMES];
    unsigned frame_head, n_frames;
    RigUsartRxCursor rx;
    int64_t line_end_ns; /* the end of the last frame the sender began */
} RigStm32UsartState;

OBJECT_DECLARE_SIMPLE_TYPE(RigStm32UsartState, RIG_STM32_USART)

/* PCLK ticks per bit: 16 x USARTDIV (OVER8 = 0, BRR as it is) or 8 x USARTDIV (OVER8 = 1, DIV_Fraction[2:0]
 * in eighths; BRR[3] must be kept clear); 30.3.4: baud = f_PCLK / (8 x (2 - OVER8) x USARTDIV) */
static inline uint64_t ticks_per_bit(const RigStm32UsartState *s)
{
    uint32_t brr = s->regs[R_BRR];
    uint64_t ticks = (s->regs[R_CR1] & CR1_OVER8) ? (brr >> 4) * 8 + (brr & 7) : brr;
    return MAX(ticks, 1); /* BRR = 0 is no rate the manual allows: the fastest there is */
}

static inline uint64_t pclk_hz(const RigStm32UsartState *s)
{
    uint64_t hz = s->rcc ? rig_stm32_rcc_pclk_hz(s->rcc, s->apb) : 16000000;
    return MAX(hz, 1);
}

/* @sixteenths of a bit of @ticks PCLK ticks at @pclk_hz in ns: muldiv64's result, in 64 bits when the
 * product fits (the receiver's samples: a 128-bit division each was a tenth of QEMU's time with SBUS) */
static inline int64_t sixteenths_ns(uint64_t sixteenths, uint64_t ticks, uint64_t pclk_hz)
{
    uint64_t a = sixteenths * ticks;
    return (int64_t)(a <= UINT64_MAX / NS ? a * NS / (pclk_hz * SIXTEENTHS) : muldiv64(a, NS, pclk_hz * SIXTEENTHS));
}

/* @sixteenths of a bit at the USART's baud in ns */
static inline int64_t bit_ns(const RigStm32UsartState *s, uint64_t sixteenths)
{
    return sixteenths_ns(sixteenths, ticks_per_bit(s), pclk_hz(s));
}

static inline unsigned data_bits(const RigStm32UsartState *s) { return (s->regs[R_CR1] & CR1_M) ? 9 : 8; }

/* A whole frame in sixteenths of a bit: start, data (with parity), stop (CR2.STOP: 1, 0.5, 2, 1.5) */
static inline uint64_t frame_sixteenths(const RigStm32UsartState *s)
{
    static const unsigned stop[4] = { 16, 8, 32, 24 };
    return (1 + data_bits(s)) * SIXTEENTHS + stop[s->regs[R_CR2] >> CR2_STOP_SHIFT & 3];
}

void rig_usart_update_irqs(RigStm32UsartState *s);
/* The receiver up to @now: its bytes into DR (and the DMA), its flags */
void rig_usart_rx_catch_up(RigStm32UsartState *s, int64_t now);
/* The instant the receiver needs its QEMU timer for (INT64_MAX: none) */
int64_t rig_usart_rx_deadline(RigStm32UsartState *s);

#endif
