/* The telemetry (telemetry.h), formatted without printf. A line goes into a ring that the DMA sends
   from, as Betaflight's serial driver does: one transfer for the bytes in the ring up to its end, the next
   started from the stream's transfer-complete interrupt, so the core spends no time a byte (a 200-byte
   line at 500000 baud is 4 ms on the wire, the whole 4 ms cycle had the loop waited for TXE as a blocking
   HAL transmit does). A line that does not fit in the ring is dropped whole (a line every telemetry_every
   cycles leaves the ring time to drain). */
#include "telemetry.h"

#include "board.h"
#include "stm32f405.h"

#define LINE_MAX 240
#define RING 1024u /* a power of two */
#define STREAM TELEMETRY_DMA_STREAM

void TELEMETRY_DMA_HANDLER(void);

static volatile char ring[RING];
static volatile uint32_t ring_head, ring_tail; /* written by telemetry_send, by the interrupt */
static volatile uint32_t in_flight;            /* the bytes of the transfer under way (0: none) */

void telemetry_init(void)
{
    TELEMETRY_USART_ENR |= TELEMETRY_USART_EN;
    RCC_AHB1ENR |= TELEMETRY_DMA_EN;
    board_pin_af(TELEMETRY_TX_PORT, TELEMETRY_TX_PIN, TELEMETRY_TX_AF); /* the board's USART TX */
    USART_BRR(TELEMETRY_USART) = (uint32_t)((TELEMETRY_USART_HZ * 2 / TELEMETRY_BAUD + 1) / 2);
    USART_CR3(TELEMETRY_USART) = USART_CR3_DMAT;
    USART_CR1(TELEMETRY_USART) = USART_CR1_UE | USART_CR1_TE;
    DMA_SPAR(TELEMETRY_DMA, STREAM) = (uint32_t)&USART_DR(TELEMETRY_USART);
    NVIC_ISER(TELEMETRY_DMA_IRQ / 32u) = 1u << (TELEMETRY_DMA_IRQ % 32u);
}

/* A transfer of the ring's bytes from the tail up to the head or the ring's end, if none is under way
   and there are any (with the DMA's interrupt masked, or from it) */
static void start_transfer(void)
{
    uint32_t tail = ring_tail, n = ring_head - tail;
    if (in_flight || n == 0)
        return;
    if (n > RING - tail % RING)
        n = RING - tail % RING;
    in_flight = n;
    DMA_IFCR(TELEMETRY_DMA, STREAM) = DMA_FLAGS_ALL << DMA_FLAGS_SHIFT(STREAM); /* (10.3.17: cleared first) */
    DMA_SM0AR(TELEMETRY_DMA, STREAM) = (uint32_t)&ring[tail % RING];
    DMA_SNDTR(TELEMETRY_DMA, STREAM) = n;
    DMA_SCR(TELEMETRY_DMA, STREAM) =
        DMA_SCR_CHSEL(TELEMETRY_DMA_CHANNEL) | DMA_SCR_M2P | DMA_SCR_MINC | DMA_SCR_TCIE | DMA_SCR_EN;
}

void telemetry_send(const char *s, unsigned n)
{
    uint32_t head = ring_head;
    if (RING - (head - ring_tail) < n)
        return;
    for (unsigned i = 0; i < n; i++)
        ring[(head + i) % RING] = s[i];
    ring_head = head + n;
    NVIC_ICER(TELEMETRY_DMA_IRQ / 32u) = 1u << (TELEMETRY_DMA_IRQ % 32u);
    start_transfer();
    NVIC_ISER(TELEMETRY_DMA_IRQ / 32u) = 1u << (TELEMETRY_DMA_IRQ % 32u);
}

void TELEMETRY_DMA_HANDLER(void)
{
    if (DMA_ISR(TELEMETRY_DMA, STREAM) >> DMA_FLAGS_SHIFT(STREAM) & DMA_TCIF) {
        DMA_IFCR(TELEMETRY_DMA, STREAM) = DMA_TCIF << DMA_FLAGS_SHIFT(STREAM);
        ring_tail += in_flight;
        in_flight = 0;
        start_transfer();
    }
}

typedef struct {
    char buf[LINE_MAX];
    unsigned n;
} line;

static void put_str(line *l, const char *s)
{
    while (*s && l->n < LINE_MAX - 1)
        l->buf[l->n++] = *s++;
}

static void put_uint(line *l, uint32_t v, unsigned min_digits)
{
    char d[10];
    unsigned k = 0;
    do {
        d[k++] = (char)('0' + v % 10);
        v /= 10;
    } while (v || k < min_digits);
    while (k && l->n < LINE_MAX - 1)
        l->buf[l->n++] = d[--k];
}

static void put_int(line *l, int32_t v)
{
    if (v < 0) {
        put_str(l, "-");
        put_uint(l, (uint32_t)(-(int64_t)v), 1);
    } else {
        put_uint(l, (uint32_t)v, 1);
    }
}

/* v to @decimals places (rounded); NaN "nan", beyond +-2e9 units "inf" */
static void put_fixed(line *l, double v, unsigned decimals)
{
    if (v != v) {
        put_str(l, "nan");
        return;
    }
    uint32_t scale = 1;
    for (unsigned i = 0; i < decimals; i++)
        scale *= 10;
    if (v < 0) {
        put_str(l, "-");
        v = -v;
    }
    if (v >= 2e9) {
        put_str(l, "inf");
        return;
    }
    uint64_t units = (uint64_t)(v * scale + 0.5);
    put_uint(l, (uint32_t)(units / scale), 1);
    if (decimals) {
        put_str(l, ".");
        put_uint(l, (uint32_t)(units % scale), decimals);
    }
}

void telemetry_say(const char *a, const char *b)
{
    line l = { .n = 0 };
    put_str(&l, "# fc: ");
    put_str(&l, a);
    put_str(&l, b);
    l.buf[l.n++] = '\n';
    telemetry_send(l.buf, l.n);
}

void telemetry_line(double t, const flight *fl, const tel_counters *k)
{
    const double deg = 180 / M_PI;
    line l = { .n = 0 };
    put_str(&l, "T t=");
    put_fixed(&l, t, 4);
    put_str(&l, " roll=");
    put_fixed(&l, fl->att.roll * deg, 3);
    put_str(&l, " pitch=");
    put_fixed(&l, fl->att.pitch * deg, 3);
    put_str(&l, " yaw=");
    put_fixed(&l, fl->att.yaw * deg, 3);
    put_str(&l, " alt=");
    put_fixed(&l, fl->altf.h, 3);
    put_str(&l, " armed=");
    put_int(&l, fl->armed);
    put_str(&l, " rc=");
    put_int(&l, fl->rc_ok);
    put_str(&l, " gyro_fault=");
    put_int(&l, fl->gyro_fault);
    put_str(&l, " loop_us=");
    put_uint(&l, k->loop_us, 1);
    put_str(&l, " max_us=");
    put_uint(&l, k->max_us, 1);
    put_str(&l, " overruns=");
    put_uint(&l, k->overruns, 1);
    put_str(&l, " cfg=");
    put_str(&l, k->cfg);
    put_str(&l, " twi_err=");
    put_uint(&l, (uint32_t)k->twi.nacks + k->twi.timeouts + k->twi.bus_errors, 1);
    put_str(&l, " twi_rec=");
    put_uint(&l, k->twi.recoveries, 1);
    put_str(&l, " sbus_ok=");
    put_uint(&l, k->sbus.frames, 1);
    put_str(&l, " sbus_bad=");
    put_uint(&l, (uint32_t)k->sbus.bad_frames + k->sbus.byte_errors, 1);
    l.buf[l.n++] = '\n';
    telemetry_send(l.buf, l.n);
}
