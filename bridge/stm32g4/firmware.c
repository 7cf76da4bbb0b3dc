/* The bridge firmware for the STM32G431 (NUCLEO-G431KB or a WeAct G431 core board; docs/bridge-
   firmware.md): the bridge core (bridge/core) over this MCU's peripherals, interrupt driven.

   Pins (DS12589 alternate functions; the 32-pin package of the NUCLEO-G431KB has them all):
     PA2 / PA3   USART2 TX / RX (AF7)       the host link, 2 Mbaud 8N1, DMA both ways: on the NUCLEO
                                            the ST-LINK's virtual COM port
     PA15 / PB7  I2C1 SCL / SDA (AF4)       target at OA1 = MPU-6050 (0x68), OA2 = MS5611 (0x77), unmasked
     PA8 / PB5   I2C3 SCL (AF2) / SDA (AF8) target at 0x1E (HMC5883L), only while the MPU's bypass is on
                                            (or the topology is direct): wired to the same SCL / SDA
     PA0 PA1     TIM2 CH1 CH2 (AF1)         ESC inputs 1, 2
     PA9 PA10    TIM2 CH3 CH4 (AF10)        ESC inputs 3, 4
     PB6         USART1 TX (AF7)            SBUS to the board's RC input: 100000 baud 8E2, inverted by
                                            the USART (TXINV), no external inverter
     PA11 / PA12 FDCAN1 RX / TX (AF9)       to a 3.3 V CAN transceiver (TI SN65HVD230 / TCAN330, or
                                            NXP TJA1051T/3): the DBC's capture frames at 500 kbit/s
     PB0         input, pull-up             tied to GND at reset: capture-only mode
   The 0x1E target is I2C3, not I2C2: on the 32-pin package I2C2's SCL is PA9 only, and PA9/PA10 are
   the only pins left for TIM2 CH3/CH4 once PA2/PA3 carry the host link.

   Concurrency: the I2C interrupts (the most urgent: a byte is due within a bit time) call the core
   directly; everything else calls it from the main loop with interrupts on, and the core masks them
   (the HAL's lock) only while it touches what the I2C events share: it decodes the host's frames,
   frames its own and encodes samples with them on. Capture edges are queued by TIM2's interrupt and
   fed from the main loop; the host's bytes arrive by circular DMA and are fed in small chunks; frames
   up go out by DMA from a ring that drops a frame that does not fit (the host sees the gap in the
   sequence).

   Capture-only mode (PB0 low at reset): the same core with no I2C target and no SBUS, for users with
   their own sensor set-up: the four ESC pulses go out as the DBC's two CAN frames with each PULSES (at
   most every 2 ms; the core's can_capture) and as PULSES on the host link. Its name is "g431 capture"
   ("stm32g431" in bridge mode; " wdt" after either when the watchdog reset it). */
#include <string.h>

#include "bridge.h"
#include "clock.h"
#include "regs.h"

#ifndef FIRMWARE_SHA
#define FIRMWARE_SHA 0x0ull /* make firmware passes the first 8 bytes of the sources' SHA-256 */
#endif

#define TICK_HZ 10000000u /* TIM2: 0.1 us */
#define I2C_PRIO 0x00u
#define TIM2_PRIO 0x10u
#define OTHER_PRIO 0x20u

static struct bridge br;
static int capture_only;

static inline uint32_t irq_save(void)
{
    uint32_t p;
    __asm volatile("mrs %0, primask\n cpsid i" : "=r"(p)::"memory");
    return p;
}

static inline void irq_restore(uint32_t p) { __asm volatile("msr primask, %0" ::"r"(p) : "memory"); }

static void irq_enable(unsigned irq, uint8_t prio)
{
    NVIC_IPR8(irq) = prio;
    NVIC_ISER(irq >> 5) = BIT(irq & 31u);
}

/* ---------------------------------------------------------------- pins */

static void pin_af(uint32_t port, unsigned pin, unsigned af, int open_drain, int pull_up)
{
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2 * pin))) | (GPIO_MODE_AF << (2 * pin));
    GPIO_OSPEEDR(port) |= 3u << (2 * pin);
    if (open_drain)
        GPIO_OTYPER(port) |= BIT(pin);
    GPIO_PUPDR(port) = (GPIO_PUPDR(port) & ~(3u << (2 * pin))) | ((pull_up ? 1u : 0u) << (2 * pin));
    GPIO_AFR(port, pin) = (GPIO_AFR(port, pin) & ~(0xFu << (4 * (pin & 7u)))) | (af << (4 * (pin & 7u)));
}

/* ---------------------------------------------------------------- time: TIM2, 32 bits at 10 MHz */

static volatile uint32_t tim2_wraps;

/* the 64-bit tick of a 32-bit count read now or captured a moment ago (interrupts masked, or TIM2's
   own interrupt): a wrap not yet counted belongs to counts below the half-way mark */
static uint64_t extend(uint32_t count)
{
    uint32_t hi = tim2_wraps;
    if ((TIM_SR(TIM2_BASE) & TIM_SR_UIF) && count < 0x80000000u)
        hi++;
    return ((uint64_t)hi << 32) | count;
}

static uint64_t now_ticks(void)
{
    uint32_t p = irq_save();
    uint64_t t = extend(TIM_CNT(TIM2_BASE));
    irq_restore(p);
    return t;
}

static uint64_t hal_now_us(void *ctx)
{
    (void)ctx;
    return now_ticks() / (TICK_HZ / 1000000u);
}

/* ---------------------------------------------------------------- capture edges */

struct edge {
    uint8_t ch, level;
    uint32_t count;
    uint64_t t_us;
};

#define EDGES 64u
static struct edge edges[EDGES];
static volatile uint32_t edge_head, edge_tail, edges_lost;

static const uint32_t CAPTURE_PORT[4] = { GPIOA_BASE, GPIOA_BASE, GPIOA_BASE, GPIOA_BASE };
static const uint8_t CAPTURE_PIN[4] = { 0, 1, 9, 10 };

void tim2_irq(void)
{
    uint32_t sr = TIM_SR(TIM2_BASE);
    for (unsigned ch = 0; ch < 4; ch++) {
        if (!(sr & TIM_SR_CCIF(ch)))
            continue;
        uint32_t count = TIM_CCR(TIM2_BASE, ch); /* reading it clears CCxIF */
        /* the level after the edge: read now, well inside any ESC pulse (>= 125 us) */
        uint8_t level = (GPIO_IDR(CAPTURE_PORT[ch]) >> CAPTURE_PIN[ch]) & 1u;
        if (sr & TIM_SR_CCOF(ch)) { /* an edge was lost: the pulse filter counts the odd edge */
            TIM_SR(TIM2_BASE) = ~TIM_SR_CCOF(ch);
            edges_lost++;
        }
        uint32_t h = edge_head;
        if (h - edge_tail >= EDGES) {
            edges_lost++;
            continue;
        }
        struct edge *e = &edges[h % EDGES];
        e->ch = (uint8_t)ch;
        e->level = level;
        e->count = count;
        e->t_us = extend(count) / (TICK_HZ / 1000000u);
        edge_head = h + 1;
    }
    if (TIM_SR(TIM2_BASE) & TIM_SR_UIF) {
        TIM_SR(TIM2_BASE) = ~TIM_SR_UIF;
        tim2_wraps++;
    }
}

static void capture_init(void)
{
    RCC_APB1ENR1 |= RCC_APB1ENR1_TIM2EN;
    for (unsigned ch = 0; ch < 4; ch++)
        pin_af(CAPTURE_PORT[ch], CAPTURE_PIN[ch], ch < 2 ? 1u : 10u, 0, 0);
    TIM_PSC(TIM2_BASE) = CLOCK_HZ / TICK_HZ - 1u;
    TIM_ARR(TIM2_BASE) = 0xFFFFFFFFu;
    /* filter 3: f_CK_INT / 8 samples, 47 ns of noise rejected; each channel captures both edges */
    TIM_CCMR1(TIM2_BASE) = TIM_CCMR_IN_TI(0u, 3u) | TIM_CCMR_IN_TI(1u, 3u);
    TIM_CCMR2(TIM2_BASE) = TIM_CCMR_IN_TI(2u, 3u) | TIM_CCMR_IN_TI(3u, 3u);
    TIM_CCER(TIM2_BASE) =
        TIM_CCER_BOTH_EDGES(0u) | TIM_CCER_BOTH_EDGES(1u) | TIM_CCER_BOTH_EDGES(2u) | TIM_CCER_BOTH_EDGES(3u);
    TIM_EGR(TIM2_BASE) = TIM_EGR_UG; /* load the prescaler */
    TIM_SR(TIM2_BASE) = 0;
    TIM_DIER(TIM2_BASE) = TIM_DIER_UIE | TIM_DIER_CCIE(0u) | TIM_DIER_CCIE(1u) | TIM_DIER_CCIE(2u) | TIM_DIER_CCIE(3u);
    TIM_CR1(TIM2_BASE) = TIM_CR1_CEN;
    irq_enable(IRQ_TIM2, TIM2_PRIO);
}

/* ---------------------------------------------------------------- host link: USART2, DMA */

#define RX_RING 512u
#define TX_RING 2048u
static uint8_t rx_ring[RX_RING];
static uint32_t rx_tail;
static uint8_t tx_ring[TX_RING];
static volatile uint32_t tx_head, tx_tail, tx_busy_len;

static void tx_kick(void)
{
    uint32_t p = irq_save();
    if (!tx_busy_len && tx_head != tx_tail) {
        uint32_t start = tx_tail % TX_RING, n = tx_head - tx_tail;
        if (start + n > TX_RING)
            n = TX_RING - start;
        tx_busy_len = n;
        DMA_CCR(2) &= ~DMA_CCR_EN;
        DMA_IFCR = DMA_IFCR_ALL(2);
        DMA_CMAR(2) = (uint32_t)(uintptr_t)&tx_ring[start];
        DMA_CNDTR(2) = n;
        DMA_CCR(2) |= DMA_CCR_EN;
    }
    irq_restore(p);
}

void dma1_ch2_irq(void)
{
    if (DMA_ISR & DMA_ISR_TCIF(2)) {
        DMA_IFCR = DMA_IFCR_ALL(2);
        tx_tail += tx_busy_len;
        tx_busy_len = 0;
        tx_kick();
    }
}

/* only the core's bridge_flush, in the main loop, writes the ring: the DMA's interrupt only moves
   tx_tail on, so the room read here can only grow before the copy is done */
static void link_send(const uint8_t *bytes, size_t n)
{
    uint32_t head = tx_head;
    if (TX_RING - (head - tx_tail) >= n) {
        for (size_t i = 0; i < n; i++)
            tx_ring[(head + i) % TX_RING] = bytes[i];
        tx_head = head + (uint32_t)n;
    }
    tx_kick();
}

static void hal_link_tx(void *ctx, const uint8_t *bytes, size_t n)
{
    (void)ctx;
    link_send(bytes, n);
}

static void link_init(void)
{
    RCC_APB1ENR1 |= RCC_APB1ENR1_USART2EN;
    RCC_AHB1ENR |= RCC_AHB1ENR_DMA1EN | RCC_AHB1ENR_DMAMUX1EN;
    pin_af(GPIOA_BASE, 2, 7, 0, 0);
    pin_af(GPIOA_BASE, 3, 7, 0, 1);
    USART_BRR(USART2_BASE) = CLOCK_HZ / 2000000u; /* 85: 2 Mbaud exactly, 16x oversampling */
    USART_CR3(USART2_BASE) = USART_CR3_DMAR | USART_CR3_DMAT | USART_CR3_OVRDIS;
    /* DMA1 channel 1: RX, circular; channel 2: TX, one chunk at a time */
    DMAMUX_CCR(1) = DMAREQ_USART2_RX;
    DMA_CPAR(1) = (uint32_t)(uintptr_t)&USART_RDR(USART2_BASE);
    DMA_CMAR(1) = (uint32_t)(uintptr_t)rx_ring;
    DMA_CNDTR(1) = RX_RING;
    DMA_CCR(1) = DMA_CCR_MINC | DMA_CCR_CIRC | DMA_CCR_EN;
    DMAMUX_CCR(2) = DMAREQ_USART2_TX;
    DMA_CPAR(2) = (uint32_t)(uintptr_t)&USART_TDR(USART2_BASE);
    DMA_CCR(2) = DMA_CCR_MINC | DMA_CCR_DIR_M2P | DMA_CCR_TCIE;
    USART_CR1(USART2_BASE) = USART_CR1_UE | USART_CR1_RE | USART_CR1_TE;
    irq_enable(IRQ_DMA1_CH2, OTHER_PRIO);
}

/* the host's bytes the DMA wrote since the last call, at most max */
static size_t link_rx_take(uint8_t *out, size_t max)
{
    uint32_t head = RX_RING - DMA_CNDTR(1);
    size_t n = 0;
    while (rx_tail != head && n < max) {
        out[n++] = rx_ring[rx_tail];
        rx_tail = (rx_tail + 1u) % RX_RING;
    }
    return n;
}

/* ---------------------------------------------------------------- SBUS: USART1, inverted 8E2 */

static uint8_t sbus_buf[SBUS_FRAME];
static volatile uint32_t sbus_len, sbus_pos;

void usart1_irq(void)
{
    if ((USART_ISR(USART1_BASE) & USART_ISR_TXE) && sbus_pos < sbus_len) {
        USART_TDR(USART1_BASE) = sbus_buf[sbus_pos++];
        if (sbus_pos == sbus_len)
            USART_CR1(USART1_BASE) &= ~USART_CR1_TXEIE;
    }
}

static size_t hal_sbus_tx(void *ctx, const uint8_t *frame, size_t n)
{
    (void)ctx;
    if (capture_only) /* no SBUS in this mode: nothing to count as dropped */
        return n;
    if (sbus_pos < sbus_len) /* the last frame is still going out */
        return 0;
    if (n > SBUS_FRAME)
        n = SBUS_FRAME;
    memcpy(sbus_buf, frame, n);
    sbus_pos = 0;
    sbus_len = (uint32_t)n;
    USART_CR1(USART1_BASE) |= USART_CR1_TXEIE;
    return n;
}

static void sbus_init(void)
{
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    pin_af(GPIOB_BASE, 6, 7, 0, 0);
    USART_BRR(USART1_BASE) = CLOCK_HZ / 100000u; /* 1700 */
    USART_CR2(USART1_BASE) = USART_CR2_STOP_2 | USART_CR2_TXINV;
    USART_CR1(USART1_BASE) = USART_CR1_M0 | USART_CR1_PCE | USART_CR1_TE | USART_CR1_UE; /* 8 data + even */
    irq_enable(IRQ_USART1, OTHER_PRIO);
}

/* ---------------------------------------------------------------- CAN: FDCAN1, classic frames */

static int hal_can_tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    if (FDCAN_TXFQS & FDCAN_TXFQS_TFQF)
        return -1;
    uint32_t i = FDCAN_TXFQS_TFQPI(FDCAN_TXFQS);
    volatile uint32_t *e = (volatile uint32_t *)(uintptr_t)FDCAN_RAM_TXBUF(i);
    uint32_t w[2] = { 0, 0 };
    for (unsigned k = 0; k < len && k < 8; k++)
        w[k / 4] |= (uint32_t)data[k] << (8 * (k % 4));
    e[0] = (id & 0x7FFu) << 18; /* standard identifier, data frame */
    e[1] = (uint32_t)(len > 8 ? 8 : len) << 16;
    e[2] = w[0];
    e[3] = w[1];
    FDCAN_TXBAR = BIT(i);
    return 0;
}

static void can_init(void)
{
    RCC_CCIPR = (RCC_CCIPR & ~RCC_CCIPR_FDCANSEL_MASK) | RCC_CCIPR_FDCANSEL_PCLK1;
    RCC_APB1ENR1 |= RCC_APB1ENR1_FDCANEN;
    pin_af(GPIOA_BASE, 11, 9, 0, 1);
    pin_af(GPIOA_BASE, 12, 9, 0, 0);
    FDCAN_CCCR |= FDCAN_CCCR_INIT;
    while (!(FDCAN_CCCR & FDCAN_CCCR_INIT)) {
    }
    FDCAN_CCCR |= FDCAN_CCCR_CCE | BIT(6); /* DAR: no automatic retransmission (a report is periodic) */
    for (uint32_t a = FDCAN1_RAM; a < FDCAN1_RAM + 0x350u; a += 4)
        REG(a) = 0;
    /* 170 MHz / 17 = 10 MHz time quanta, 1 + 16 + 3 = 20 per bit: 500 kbit/s, sample point 85 % */
    FDCAN_NBTP = FDCAN_NBTP_VAL(3u, 17u, 16u, 3u);
    FDCAN_RXGFC = FDCAN_RXGFC_REJECT_ALL; /* it only sends */
    FDCAN_TXBC = 0;                       /* Tx FIFO */
    FDCAN_CCCR &= ~FDCAN_CCCR_INIT;
    while (FDCAN_CCCR & FDCAN_CCCR_INIT) {
    }
}

/* ---------------------------------------------------------------- I2C targets: I2C1 and I2C3 */

/* The targets do not stretch SCL (NOSTRETCH, as the real chips do not): the ADDR event is not waited
   for, so a read's first byte goes out from TXDR as the address is acknowledged and must be there
   before (RM0440 §41.4.8, "Target transmitter": with NOSTRETCH the first byte is programmed before the
   address match, and STOPF is cleared only after it is, or it underruns). The core gives that byte
   through i2c_preload at every change that may alter it: a STOP, the master's NACK, a byte written,
   the chips' time moving at a poll. Each later byte is due within a byte time of its TXIS, each
   received byte must be read within one of its RXNE: the I2C interrupts have the top priority and
   the main loop masks them for copies only. */
struct i2c_port {
    uint32_t base;
    int nack;             /* the core refused this transaction: writes are dropped, reads give 0xFF */
    volatile int sending; /* addressed to read: TXDR is the transfer's until the NACK or the STOP */
};

static struct i2c_port i2c1 = { I2C1_BASE, 0, 0 }, i2c3 = { I2C3_BASE, 0, 0 }; /* the core's ports 0, 1 */

static uint64_t now_ns(void) { return now_ticks() * (1000000000u / TICK_HZ); }

/* the next read's first byte into TXDR, unless the target is sending or its address has just matched
   (then TXDR may already be in the shift register: the core keeps what it knows the port holds) */
static int hal_i2c_preload(void *ctx, unsigned index, uint8_t byte)
{
    (void)ctx;
    struct i2c_port *port = index ? &i2c3 : &i2c1;
    if (capture_only)
        return 0;
    uint32_t p = irq_save();
    int free = !port->sending && !(I2C_ISR(port->base) & I2C_ISR_ADDR);
    if (free) {
        I2C_ISR(port->base) = I2C_ISR_TXE; /* flush what it held */
        I2C_TXDR(port->base) = byte;
    }
    irq_restore(p);
    return free;
}

static void i2c_event(struct i2c_port *port)
{
    uint32_t base = port->base;
    uint32_t isr = I2C_ISR(base);
    uint64_t t = now_ns();
    if (isr & I2C_ISR_RXNE) { /* (the core preloads from the pointer just written: a repeated START may read) */
        uint8_t byte = (uint8_t)I2C_RXDR(base);
        if (!port->nack && !bridge_i2c_write(&br, t, byte))
            port->nack = 1;
    }
    if (isr & I2C_ISR_NACKF) { /* the master's NACK after its last byte (before a STOP or a repeated START) */
        /* TXDR took the next byte as the last one went out (RM0440 §41.4.7): it was never sent, so the
           chip gets it back (a FIFO byte stays in the FIFO); then the next read's first byte */
        if (!(I2C_ISR(base) & I2C_ISR_TXE))
            bridge_i2c_unread(&br);
        I2C_ISR(base) = I2C_ISR_TXE;
        I2C_ICR(base) = I2C_ICR_NACKCF;
        port->sending = 0;
        bridge_i2c_preload_all(&br);
    }
    if (isr & I2C_ISR_STOPF) {
        port->sending = 0;
        bridge_i2c_stop(&br, t); /* preloads the next read's first byte: only then STOPF is cleared */
        I2C_ICR(base) = I2C_ICR_STOPCF;
    }
    if (isr & I2C_ISR_ADDR) {
        int read = (isr & I2C_ISR_DIR) != 0;
        port->sending = read; /* its first byte, the one preloaded, is going out: the core reads it */
        port->nack = !bridge_i2c_start(&br, t, (uint8_t)I2C_ISR_ADDCODE(isr), read);
        I2C_ICR(base) = I2C_ICR_ADDRCF;
    }
    if (port->sending && (I2C_ISR(base) & I2C_ISR_TXIS))
        I2C_TXDR(base) = port->nack ? 0xFFu : bridge_i2c_read(&br, t);
}

static void i2c_setup(uint32_t base)
{
    I2C_CR1(base) = 0;
    /* I2CCLK = PCLK1 = 170 MHz. Target timing (RM0440 §41.4.5): PRESC 3 (23.5 ns); SDADEL 3: SDA
       changes 76 ns after SCL's fall is seen (plus the analog filter's delay), a hold that needs SCL to
       fall in under about 150 ns (the I2C worst case, 300 ns at 400 kHz, would want SDADEL 10, which
       at 1 MHz leaves the data too late for the master's setup); SCLDEL 10 (259 ns) would make setup
       by stretching, which NOSTRETCH does not do. The analog filter on. */
    I2C_TIMINGR(base) = (3u << 28) | (10u << 20) | (3u << 16);
    /* SCL low for 25 ms: a stuck bus (TIMEOUTA = 25 ms * 170 MHz / 2048 - 1) */
    I2C_TIMEOUTR(base) = 2074u | I2C_TIMEOUTR_TIMOUTEN;
    /* NOSTRETCH may only change while PE is 0: configured first, then enabled */
    I2C_CR1(base) = I2C_CR1_NOSTRETCH | I2C_CR1_ADDRIE | I2C_CR1_RXIE | I2C_CR1_TXIE | I2C_CR1_STOPIE | I2C_CR1_NACKIE |
                    I2C_CR1_ERRIE;
    I2C_CR1(base) |= I2C_CR1_PE;
}

/* OVR is a byte the interrupt came too late for (NOSTRETCH: an underrun sends 0xFF, an overrun loses
   the byte): counted, the transfer goes on. A bus error or a lost arbitration ends the transfer; SCL
   held low for 25 ms (TIMEOUT) resets the peripheral. */
static void i2c_error(struct i2c_port *port)
{
    uint32_t isr = I2C_ISR(port->base);
    I2C_ICR(port->base) = I2C_ICR_ALL & ~(I2C_ICR_ADDRCF | I2C_ICR_NACKCF | I2C_ICR_STOPCF);
    br.n.i2c_errors++;
    if (!(isr & (I2C_ISR_BERR | I2C_ISR_ARLO | I2C_ISR_TIMEOUT)))
        return;
    if (isr & I2C_ISR_TIMEOUT) { /* SCL held low: let go of the bus (PE off resets the peripheral) */
        uint32_t oar1 = I2C_OAR1(port->base), oar2 = I2C_OAR2(port->base);
        i2c_setup(port->base);
        I2C_OAR1(port->base) = oar1;
        I2C_OAR2(port->base) = oar2;
    }
    port->sending = 0;
    bridge_i2c_stop(&br, now_ns()); /* (and the next read's first byte preloaded) */
}

void i2c1_ev_irq(void) { i2c_event(&i2c1); }
void i2c1_er_irq(void) { i2c_error(&i2c1); }
void i2c3_ev_irq(void) { i2c_event(&i2c3); }
void i2c3_er_irq(void) { i2c_error(&i2c3); }

/* The core's addresses: the MPU-6050's (0x68/0x69) is I2C1's OA1, the MS5611's (0x76/0x77) its OA2
   without a mask, the HMC5883L's I2C3's OA1. An own address is changed only while disabled. */
static void hal_i2c_addr_enable(void *ctx, uint8_t addr, int on)
{
    (void)ctx;
    if (capture_only)
        return;
    volatile uint32_t *oar = addr == 0x68 || addr == 0x69   ? &I2C_OAR1(I2C1_BASE)
                             : addr == 0x76 || addr == 0x77 ? &I2C_OAR2(I2C1_BASE)
                                                            : &I2C_OAR1(I2C3_BASE);
    *oar = 0;
    if (on) {
        *oar = I2C_OAR_7BIT(addr);
        *oar = I2C_OAR_7BIT(addr) | I2C_OAR_EN;
    }
}

static void i2c_init(void)
{
    RCC_APB1ENR1 |= RCC_APB1ENR1_I2C1EN | RCC_APB1ENR1_I2C3EN;
    RCC_APB2ENR |= RCC_APB2ENR_SYSCFGEN;
    (void)RCC_APB2ENR;
    /* Fast-mode Plus drive on the target pins: SDA must pull strong pull-ups down at 1 MHz */
    SYSCFG_CFGR1 |= SYSCFG_CFGR1_I2C1_FMP | SYSCFG_CFGR1_I2C3_FMP;
    pin_af(GPIOA_BASE, 15, 4, 1, 1);
    pin_af(GPIOB_BASE, 7, 4, 1, 1);
    pin_af(GPIOA_BASE, 8, 2, 1, 1);
    pin_af(GPIOB_BASE, 5, 8, 1, 1);
    i2c_setup(I2C1_BASE);
    i2c_setup(I2C3_BASE);
    irq_enable(IRQ_I2C1_EV, I2C_PRIO);
    irq_enable(IRQ_I2C1_ER, I2C_PRIO);
    irq_enable(IRQ_I2C3_EV, I2C_PRIO);
    irq_enable(IRQ_I2C3_ER, I2C_PRIO);
}

/* ---------------------------------------------------------------- main */

/* (the capture's state is the main loop's alone: no lock) */
static void feed_edges(void)
{
    while (edge_tail != edge_head) {
        struct edge e = edges[edge_tail % EDGES];
        edge_tail = edge_tail + 1;
        bridge_capture_edge(&br, e.ch, e.level, e.count, e.t_us);
    }
}

static uint32_t hal_lock(void *ctx)
{
    (void)ctx;
    return irq_save();
}

static void hal_unlock(void *ctx, uint32_t saved)
{
    (void)ctx;
    irq_restore(saved);
}

int main(void)
{
    clock_init_170mhz();
    int watchdog_reset = watchdog_start();
    RCC_AHB2ENR |= RCC_AHB2ENR_GPIOAEN | RCC_AHB2ENR_GPIOBEN;
    (void)RCC_AHB2ENR;
    GPIO_MODER(GPIOB_BASE) &= ~(3u << 0); /* PB0: input with pull-up */
    GPIO_PUPDR(GPIOB_BASE) = (GPIO_PUPDR(GPIOB_BASE) & ~3u) | 1u;
    for (volatile unsigned i = 0; i < 1000; i++) { /* let the pull-up settle */
    }
    capture_only = !(GPIO_IDR(GPIOB_BASE) & 1u);
    capture_init();
    link_init();
    can_init();

    struct bridge_hal hal = { .now_us = hal_now_us,
                              .i2c_addr_enable = hal_i2c_addr_enable,
                              .link_tx = hal_link_tx,
                              .sbus_tx = hal_sbus_tx,
                              .can_tx = hal_can_tx,
                              .i2c_preload = hal_i2c_preload,
                              .lock = hal_lock,
                              .unlock = hal_unlock };
    struct bridge_cfg cfg = bridge_defaults();
    memset(cfg.id, 0, sizeof cfg.id);
    const char *name = capture_only ? (watchdog_reset ? "g431 capture wdt" : "g431 capture")
                                    : (watchdog_reset ? "stm32g431 wdt" : "stm32g431");
    size_t len = strlen(name);
    memcpy(cfg.id, name, len < sizeof cfg.id ? len : sizeof cfg.id); /* NUL-padded when shorter */
    for (unsigned i = 0; i < 8; i++)
        cfg.fw_sha[i] = (uint8_t)((unsigned long long)FIRMWARE_SHA >> (56 - 8 * i));
    cfg.clock_hz = CLOCK_HZ;
    cfg.capture.counter_bits = 32;
    cfg.capture.tick_hz = TICK_HZ;
    uint32_t p = irq_save();
    if (!capture_only) {
        sbus_init();
        i2c_init(); /* (no address enabled yet: nothing to answer until bridge_init sets them) */
    }
    bridge_init(&br, &hal, &cfg); /* sets the I2C addresses: the peripherals are clocked by now */
    irq_restore(p);

    uint64_t next_poll = 0;
    for (;;) {
        watchdog_feed();
        feed_edges();
        uint8_t chunk[32];
        size_t n = link_rx_take(chunk, sizeof chunk);
        if (n)
            bridge_link_rx(&br, chunk, n);
        uint64_t t = hal_now_us(NULL);
        if (t >= next_poll) {
            next_poll = t + 100u;
            bridge_poll(&br);
        }
        bridge_idle(&br); /* the next samples' register bytes ready before their instant; frames out */
    }
}
