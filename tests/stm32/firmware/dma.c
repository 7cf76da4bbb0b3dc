/* The DMA test firmware of the STM32 tier (tests/stm32/test_dma.py judges its reports against RM0090
   section 10), at the reset clock (16 MHz HSI, the APB1 timer clock 16 MHz): DMA1's and DMA2's registers
   at reset, with all ones written and while a stream is enabled; memory-to-memory copies on DMA2 stream 0
   with byte, half-word and word widths, packing (bytes in, words out) and a fixed source, their HT and TC
   flags and interrupt; a transfer error to an address nothing answers; TIM4's update requests writing a
   table into CCR1 through DMA1 stream 6 in circular mode, one value a period, as DShot's bursts do (the
   engine's pulse trace shows the widths); and the MPU-6050's 14-byte burst read by I2C1 through DMA1
   stream 0 with CR2.LAST, as ST's HAL_I2C_Mem_Read_DMA does, against the same burst read by polling. */
#include "i2c_hal_poll.h"
#include "timer_checks.h"

/* RM0090 10.5 (DMA registers) and table 10 (addresses) */
#define DMA1_BASE 0x40026000u
#define DMA2_BASE 0x40026400u
#define DMA_LISR(d) REG((d) + 0x00u)
#define DMA_HISR(d) REG((d) + 0x04u)
#define DMA_LIFCR(d) REG((d) + 0x08u)
#define DMA_HIFCR(d) REG((d) + 0x0Cu)
#define DMA_SCR(d, n) REG((d) + 0x10u + 0x18u * (n))
#define DMA_SNDTR(d, n) REG((d) + 0x14u + 0x18u * (n))
#define DMA_SPAR(d, n) REG((d) + 0x18u + 0x18u * (n))
#define DMA_SM0AR(d, n) REG((d) + 0x1Cu + 0x18u * (n))
#define DMA_SM1AR(d, n) REG((d) + 0x20u + 0x18u * (n))
#define DMA_SFCR(d, n) REG((d) + 0x24u + 0x18u * (n))
#define CR_EN (1u << 0)
#define CR_TEIE (1u << 2)
#define CR_HTIE (1u << 3)
#define CR_TCIE (1u << 4)
#define CR_M2P (1u << 6)
#define CR_M2M (2u << 6)
#define CR_CIRC (1u << 8)
#define CR_PINC (1u << 9)
#define CR_MINC (1u << 10)
#define CR_PSIZE(n) ((n) << 11) /* 0 byte, 1 half-word, 2 word */
#define CR_MSIZE(n) ((n) << 13)
#define CR_CHSEL(n) ((uint32_t)(n) << 25)
#define FLAG_TEIF (1u << 3)
#define FLAG_HTIF (1u << 4)
#define FLAG_TCIF (1u << 5)
#define FLAGS 0x3Du
#define RCC_AHB1ENR_DMA1EN (1u << 21)
#define RCC_AHB1ENR_DMA2EN (1u << 22)
#define RCC_APB1ENR_TIM3EN (1u << 1)
#define RCC_APB1ENR_TIM4EN (1u << 2)
#define TIM_DIER_UDE (1u << 8)
#define I2C_CR2_DMAEN (1u << 11)
#define I2C_CR2_LAST (1u << 12)
#define DMA1_STREAM0_IRQ 11u
#define DMA1_STREAM2_IRQ 13u
#define DMA1_STREAM6_IRQ 17u
#define DMA2_STREAM0_IRQ 56u
#define UNMAPPED 0x60000000u /* FSMC bank 1: nothing there on this board */

static const uint32_t dma_bases[2] = { DMA1_BASE, DMA2_BASE };

static void report2(const char *prefix, unsigned index, const char *suffix, uint32_t value)
{
    char name[40];
    unsigned n = 0;
    while (*prefix && n < sizeof name - 2) {
        name[n++] = *prefix++;
    }
    name[n++] = (char)('0' + index);
    while (*suffix && n < sizeof name - 1) {
        name[n++] = *suffix++;
    }
    name[n] = '\0';
    report(name, value);
}

static void nvic_enable(unsigned irq) { NVIC_ISER(irq / 32u) = 1u << (irq % 32u); }

static void registers(void)
{
    DMA_SCR(DMA1_BASE, 0) = CR_MINC; /* its clock is off: lost */
    report("dma1_s0cr_unclocked", DMA_SCR(DMA1_BASE, 0));
    RCC_AHB1ENR |= RCC_AHB1ENR_DMA1EN | RCC_AHB1ENR_DMA2EN;
    for (unsigned d = 0; d < 2; d++) {
        uint32_t base = dma_bases[d], any = DMA_LISR(base) | DMA_HISR(base), fcr_and = 0xFFFFFFFFu, fcr_or = 0;
        for (unsigned n = 0; n < 8; n++) {
            any |= DMA_SCR(base, n) | DMA_SNDTR(base, n) | DMA_SPAR(base, n) | DMA_SM0AR(base, n) | DMA_SM1AR(base, n);
            fcr_and &= DMA_SFCR(base, n);
            fcr_or |= DMA_SFCR(base, n);
        }
        report2("dma", d + 1, "_or_of_registers", any);
        report2("dma", d + 1, "_fcr_and", fcr_and);
        report2("dma", d + 1, "_fcr_or", fcr_or);
    }
    DMA_SCR(DMA2_BASE, 3) = 0xFFFFFFFEu; /* all but EN */
    DMA_SNDTR(DMA2_BASE, 3) = 0xFFFFFFFFu;
    DMA_SPAR(DMA2_BASE, 3) = 0xFFFFFFFFu;
    DMA_SM0AR(DMA2_BASE, 3) = 0xFFFFFFFFu;
    DMA_SM1AR(DMA2_BASE, 3) = 0xFFFFFFFFu;
    DMA_SFCR(DMA2_BASE, 3) = 0xFFFFFFFFu;
    DMA_LISR(DMA2_BASE) = 0xFFFFFFFFu;
    DMA_LIFCR(DMA2_BASE) = 0xFFFFFFFFu;
    report("cr_ones", DMA_SCR(DMA2_BASE, 3));
    report("ndtr_ones", DMA_SNDTR(DMA2_BASE, 3));
    report("par_ones", DMA_SPAR(DMA2_BASE, 3));
    report("m0ar_ones", DMA_SM0AR(DMA2_BASE, 3));
    report("m1ar_ones", DMA_SM1AR(DMA2_BASE, 3));
    report("fcr_ones", DMA_SFCR(DMA2_BASE, 3));
    report("lisr_ones", DMA_LISR(DMA2_BASE));
    report("lifcr_read", DMA_LIFCR(DMA2_BASE));
    DMA_SCR(DMA2_BASE, 3) = 0;
    DMA_SFCR(DMA2_BASE, 3) = 0x21u;

    /* DMA1 stream 2 on channel 0 (SPI3_RX, which nothing raises) enabled: its configuration is locked */
    DMA_SPAR(DMA1_BASE, 2) = 0x40005410u;
    DMA_SNDTR(DMA1_BASE, 2) = 5u;
    DMA_SCR(DMA1_BASE, 2) = CR_MINC | CR_MSIZE(2u);
    DMA_SCR(DMA1_BASE, 2) |= CR_EN;
    report("enabled_cr", DMA_SCR(DMA1_BASE, 2)); /* direct mode: MSIZE forced to PSIZE */
    DMA_SCR(DMA1_BASE, 2) = CR_EN | CR_MINC | CR_PSIZE(2u) | CR_TCIE | CR_CIRC;
    DMA_SNDTR(DMA1_BASE, 2) = 9u;
    DMA_SPAR(DMA1_BASE, 2) = 0x20000000u;
    DMA_SFCR(DMA1_BASE, 2) = 0x87u;
    report("locked_cr", DMA_SCR(DMA1_BASE, 2));
    report("locked_ndtr", DMA_SNDTR(DMA1_BASE, 2));
    report("locked_par", DMA_SPAR(DMA1_BASE, 2));
    report("locked_fcr", DMA_SFCR(DMA1_BASE, 2));
    DMA_SCR(DMA1_BASE, 2) &= ~CR_EN; /* disabled under way */
    report("disabled_cr", DMA_SCR(DMA1_BASE, 2));
    report("disabled_lisr", DMA_LISR(DMA1_BASE));
    report("disabled_ndtr", DMA_SNDTR(DMA1_BASE, 2));
    DMA_LIFCR(DMA1_BASE) = 0xFFFFFFFFu;
    report("cleared_lisr", DMA_LISR(DMA1_BASE));
}

static volatile uint32_t m2m_irqs, m2m_flags;

void dma2_stream0_handler(void)
{
    uint32_t flags = DMA_LISR(DMA2_BASE) & FLAGS;
    DMA_LIFCR(DMA2_BASE) = flags;
    m2m_flags |= flags;
    m2m_irqs++;
}

/* the source: byte i is i * 7 + 3 (the test computes the same) */
static uint8_t source[32] __attribute__((aligned(4)));
static uint8_t destination[40] __attribute__((aligned(4)));

static uint32_t word_at(const uint8_t *bytes) { return *(const uint32_t *)(const void *)bytes; }

/* DMA2 stream 0 copying @items of PSIZE @psize from @src to @destination (MSIZE @msize), @inc its PINC and
   MINC bits; reports under @name: the first and last words written, the word after them (untouched: 0),
   the stream's CR and NDTR after, the flags its interrupt saw and how many times it ran */
static void copy(const char *name, unsigned psize, unsigned msize, uint32_t inc, const void *src, uint32_t items)
{
    char label[32];
    unsigned n = 0;
    while (*name) {
        label[n++] = *name++;
    }
    uint32_t bytes = items << psize;
    for (unsigned i = 0; i < sizeof destination; i++) {
        destination[i] = 0;
    }
    m2m_irqs = m2m_flags = 0;
    DMA_SPAR(DMA2_BASE, 0) = (uint32_t)src;
    DMA_SM0AR(DMA2_BASE, 0) = (uint32_t)destination;
    DMA_SNDTR(DMA2_BASE, 0) = items;
    DMA_SCR(DMA2_BASE, 0) = CR_M2M | CR_PSIZE(psize) | CR_MSIZE(msize) | inc | CR_TCIE | CR_HTIE;
    DMA_SCR(DMA2_BASE, 0) |= CR_EN; /* memory-to-memory: runs at once */
    const char *suffixes[7] = { "_first", "_last", "_after", "_cr", "_ndtr", "_flags", "_irqs" };
    uint32_t values[7] = {
        word_at(destination),
        word_at(destination + bytes - 4),
        word_at(destination + bytes),
        DMA_SCR(DMA2_BASE, 0),
        DMA_SNDTR(DMA2_BASE, 0),
        m2m_flags,
        m2m_irqs,
    };
    for (unsigned k = 0; k < 7; k++) {
        unsigned m = n;
        for (const char *c = suffixes[k]; *c;) {
            label[m++] = *c++;
        }
        label[m] = '\0';
        report(label, values[k]);
    }
}

static void memory_to_memory(void)
{
    static const uint32_t fill = 0xA5C3E10Fu;
    for (unsigned i = 0; i < sizeof source; i++) {
        source[i] = (uint8_t)(i * 7u + 3u);
    }
    nvic_enable(DMA2_STREAM0_IRQ);
    copy("m2m8", 0, 0, CR_PINC | CR_MINC, source, 32);
    copy("m2m16", 1, 1, CR_PINC | CR_MINC, source, 16);
    copy("m2m32", 2, 2, CR_PINC | CR_MINC, source, 8);
    copy("pack", 0, 2, CR_PINC | CR_MINC, source, 16); /* FIFO mode (forced): four bytes a word */
    copy("fill", 2, 2, CR_MINC, &fill, 4);
    report("m2m_fcr", DMA_SFCR(DMA2_BASE, 0)); /* DMDIS set by memory-to-memory */

    /* DMA2 stream 1: to an address nothing answers */
    DMA_SPAR(DMA2_BASE, 1) = (uint32_t)source;
    DMA_SM0AR(DMA2_BASE, 1) = UNMAPPED;
    DMA_SNDTR(DMA2_BASE, 1) = 4u;
    DMA_SCR(DMA2_BASE, 1) = CR_M2M | CR_PSIZE(2u) | CR_MSIZE(2u) | CR_PINC | CR_MINC | CR_TEIE;
    DMA_SCR(DMA2_BASE, 1) |= CR_EN;
    report("error_lisr", DMA_LISR(DMA2_BASE));
    report("error_cr", DMA_SCR(DMA2_BASE, 1));
    report("error_ndtr", DMA_SNDTR(DMA2_BASE, 1));
    DMA_LIFCR(DMA2_BASE) = 0xFFFFFFFFu;

    /* DMA1 stream 1 memory-to-memory, reserved PSIZE (11) and all of NDTR: DMA2's only, nothing moves */
    destination[0] = 0;
    DMA_SPAR(DMA1_BASE, 1) = (uint32_t)source;
    DMA_SM0AR(DMA1_BASE, 1) = (uint32_t)destination;
    DMA_SNDTR(DMA1_BASE, 1) = 0xFFFFu;
    DMA_SCR(DMA1_BASE, 1) = CR_M2M | CR_PSIZE(3u) | CR_PINC | CR_MINC;
    DMA_SCR(DMA1_BASE, 1) |= CR_EN;
    report("dma1_m2m_lisr", DMA_LISR(DMA1_BASE));
    report("dma1_m2m_cr_en", DMA_SCR(DMA1_BASE, 1) & CR_EN);
    report("dma1_m2m_ndtr", DMA_SNDTR(DMA1_BASE, 1));
    report("dma1_m2m_destination", destination[0]);
    DMA_LIFCR(DMA1_BASE) = 0xFFFFFFFFu;
}

/* DShot-like: TIM4 CH1's compare values, one a period, from TIM4_UP's requests (DMA1 stream 6, channel 2) */
#define TIM4_PSC 15u /* 16 MHz / 16: 1 us */
#define TIM4_ARR 99u /* 100 us */
static const uint16_t table[8] = { 10, 25, 40, 55, 70, 85, 30, 60 };
static volatile uint32_t rounds, halves;

/* Betaflight's DShot by "DMA burst" (RM0090 17.3.19): TIM1's update requests (DMA2 stream 5, channel 6)
   write TIM1_DMAR, which DCR points at CCR1 for four transfers (DBA 13, DBL 3): one frame of four compare
   values a period, three frames in circular mode; the interrupt stops TIM1 at the second TC */
#define TIM1_DMAR REG(TIM1_BASE + 0x4Cu)
#define TIM1_DCR REG(TIM1_BASE + 0x48u)
#define DCR_CCR1_BURST_OF_4 (13u | 3u << 8)
#define TIM1_ARR 499u /* 500 us */
#define DMA2_STREAM5_IRQ 68u
#define RCC_APB2ENR_TIM1EN (1u << 0)
static const uint32_t frames[3][4] = { { 100, 200, 300, 400 }, { 150, 250, 350, 450 }, { 120, 220, 320, 420 } };
static volatile uint32_t burst_rounds;

void dma2_stream5_handler(void)
{
    uint32_t flags = DMA_HISR(DMA2_BASE) >> 6 & FLAGS; /* stream 5: bits 6-11 of HISR */
    DMA_HIFCR(DMA2_BASE) = flags << 6;
    if ((flags & FLAG_TCIF) && ++burst_rounds == 2) {
        TIM_CR1(TIM1_BASE) &= ~TIM_CR1_CEN;
    }
}

static void timer_burst_dma(void)
{
    RCC_APB2ENR |= RCC_APB2ENR_TIM1EN;
    TIM_CCMR1(TIM1_BASE) = (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) * 0x101u; /* channels 1 and 2 */
    TIM_CCMR2(TIM1_BASE) = (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) * 0x101u; /* 3 and 4 */
    TIM_CCER(TIM1_BASE) = TIM_CCER_E(1) | TIM_CCER_E(2) | TIM_CCER_E(3) | TIM_CCER_E(4);
    TIM_BDTR(TIM1_BASE) = TIM_BDTR_MOE;
    TIM1_DCR = DCR_CCR1_BURST_OF_4;
    TIM_DIER(TIM1_BASE) = TIM_DIER_UDE;
    DMA_SPAR(DMA2_BASE, 5) = (uint32_t)&TIM1_DMAR;
    DMA_SM0AR(DMA2_BASE, 5) = (uint32_t)frames;
    DMA_SNDTR(DMA2_BASE, 5) = 12u;
    DMA_SCR(DMA2_BASE, 5) = CR_CHSEL(6u) | CR_M2P | CR_CIRC | CR_MINC | CR_PSIZE(2u) | CR_MSIZE(2u) | CR_TCIE;
    DMA_SCR(DMA2_BASE, 5) |= CR_EN;
    nvic_enable(DMA2_STREAM5_IRQ);
    timer_start(TIM1_BASE, TIM4_PSC, TIM1_ARR, TIM_CR1_ARPE);
    while (burst_rounds < 2) {
        __asm volatile("wfi");
    }
    for (unsigned ch = 1; ch <= 4; ch++) {
        report2("burst_ccr", ch, "", TIM_CCR(TIM1_BASE, ch));
    }
    report("burst_dcr", TIM1_DCR);
    DMA_SCR(DMA2_BASE, 5) &= ~CR_EN;
}

/* Double-buffer mode on TIM3's update requests (DMA1 stream 2, channel 5): four words from a source in
   SRAM (PINC) into M0AR's buffer, then M1AR's, each round; the interrupt adds 0x10 to the source at each
   TC, keeps CT, and after the first round (M1 current) points M0AR at a third buffer (allowed) and M1AR
   at the first (refused) */
#define CR_DBM (1u << 18)
#define CR_CT (1u << 19)
static volatile uint32_t db_source[4];
static volatile uint32_t db_buffers[3][4];
static volatile uint32_t db_rounds, db_ct[3];

static void double_buffer_tc(void)
{
    db_ct[db_rounds] = DMA_SCR(DMA1_BASE, 2) & CR_CT;
    for (unsigned i = 0; i < 4; i++) {
        db_source[i] += 0x10u;
    }
    if (++db_rounds == 1) {
        DMA_SM0AR(DMA1_BASE, 2) = (uint32_t)db_buffers[2];
        DMA_SM1AR(DMA1_BASE, 2) = (uint32_t)db_buffers[0];
    } else if (db_rounds == 3) {
        TIM_CR1(TIM3_BASE) &= ~TIM_CR1_CEN;
    }
}

void dma1_stream2_handler(void)
{
    uint32_t flags = DMA_LISR(DMA1_BASE) >> 16 & FLAGS; /* stream 2: bits 16-21 of LISR */
    DMA_LIFCR(DMA1_BASE) = flags << 16;
    if (flags & FLAG_TCIF) {
        double_buffer_tc();
    }
}

void dma1_stream6_handler(void)
{
    uint32_t flags = DMA_HISR(DMA1_BASE) >> 16 & FLAGS; /* stream 6: bits 16-21 of HISR */
    DMA_HIFCR(DMA1_BASE) = flags << 16;
    halves += (flags & FLAG_HTIF) != 0;
    if ((flags & FLAG_TCIF) && ++rounds == 2) {
        TIM_CR1(TIM4_BASE) &= ~TIM_CR1_CEN; /* two rounds of the table */
    }
}

static void double_buffer_mode(void)
{
    for (unsigned i = 0; i < 4; i++) {
        db_source[i] = 0x1000u * (i + 1u);
    }
    RCC_APB1ENR |= RCC_APB1ENR_TIM3EN;
    TIM_DIER(TIM3_BASE) = TIM_DIER_UDE;
    DMA_SPAR(DMA1_BASE, 2) = (uint32_t)db_source;
    DMA_SM0AR(DMA1_BASE, 2) = (uint32_t)db_buffers[0];
    DMA_SM1AR(DMA1_BASE, 2) = (uint32_t)db_buffers[1];
    DMA_SNDTR(DMA1_BASE, 2) = 4u;
    DMA_SCR(DMA1_BASE, 2) = CR_CHSEL(5u) | CR_DBM | CR_PINC | CR_MINC | CR_PSIZE(2u) | CR_MSIZE(2u) | CR_TCIE;
    DMA_SCR(DMA1_BASE, 2) |= CR_EN;
    nvic_enable(DMA1_STREAM2_IRQ);
    timer_start(TIM3_BASE, TIM4_PSC, TIM4_ARR, TIM_CR1_ARPE);
    while (db_rounds < 3) {
        __asm volatile("wfi");
    }
    DMA_SCR(DMA1_BASE, 2) &= ~CR_EN;
    for (unsigned b = 0; b < 3; b++) {
        report2("db_buffer", b, "_first", db_buffers[b][0]);
        report2("db_buffer", b, "_last", db_buffers[b][3]);
        report2("db_ct", b, "", db_ct[b]);
    }
    report("db_m0ar_is_buffer2", DMA_SM0AR(DMA1_BASE, 2) == (uint32_t)db_buffers[2]);
    report("db_m1ar_is_buffer1", DMA_SM1AR(DMA1_BASE, 2) == (uint32_t)db_buffers[1]);
}

/* A request storm: TIM7's update DMA writing UG into TIM7_EGR, each write an update and a request again
   (circular, DMA1 stream 4, channel 1). The engine paces it; the core goes on and stops it. */
#define RCC_APB1ENR_TIM7EN (1u << 5)
static void request_storm(void)
{
    static const uint32_t ug = TIM_EGR_UG;
    RCC_APB1ENR |= RCC_APB1ENR_TIM7EN;
    TIM_DIER(TIM7_BASE) = TIM_DIER_UDE;
    DMA_SPAR(DMA1_BASE, 4) = (uint32_t)&TIM_EGR(TIM7_BASE);
    DMA_SM0AR(DMA1_BASE, 4) = (uint32_t)&ug;
    DMA_SNDTR(DMA1_BASE, 4) = 1u;
    DMA_SCR(DMA1_BASE, 4) = CR_CHSEL(1u) | CR_M2P | CR_CIRC | CR_PSIZE(2u) | CR_MSIZE(2u);
    DMA_SCR(DMA1_BASE, 4) |= CR_EN;
    TIM_EGR(TIM7_BASE) = TIM_EGR_UG;
    for (unsigned i = 0; i < 100u; i++) {
        __asm volatile("nop");
    }
    DMA_SCR(DMA1_BASE, 4) &= ~CR_EN;
    report("storm_stopped_cr_en", DMA_SCR(DMA1_BASE, 4) & CR_EN);
    report("storm_tcif", DMA_HISR(DMA1_BASE) & FLAG_TCIF);
    DMA_HIFCR(DMA1_BASE) = 0xFFFFFFFFu;
}

/* Memory-to-peripheral from an address nothing answers, in FIFO mode with bytes packed into words: TIM6's
   update request (DMA1 stream 1, channel 7) finds a bus error on the first byte */
#define RCC_APB1ENR_TIM6EN (1u << 4)
#define FCR_DMDIS (1u << 2)
static void peripheral_transfer_error(void)
{
    static volatile uint32_t target;
    RCC_APB1ENR |= RCC_APB1ENR_TIM6EN;
    TIM_DIER(TIM6_BASE) = TIM_DIER_UDE;
    DMA_SPAR(DMA1_BASE, 1) = (uint32_t)&target;
    DMA_SM0AR(DMA1_BASE, 1) = UNMAPPED;
    DMA_SNDTR(DMA1_BASE, 1) = 2u;
    DMA_SFCR(DMA1_BASE, 1) = FCR_DMDIS;
    DMA_SCR(DMA1_BASE, 1) = CR_CHSEL(7u) | CR_M2P | CR_MINC | CR_PSIZE(2u) | CR_MSIZE(0u);
    DMA_SCR(DMA1_BASE, 1) |= CR_EN;
    TIM_EGR(TIM6_BASE) = TIM_EGR_UG;
    report("m2p_error_lisr", DMA_LISR(DMA1_BASE));
    report("m2p_error_cr_en", DMA_SCR(DMA1_BASE, 1) & CR_EN);
    report("m2p_error_ndtr", DMA_SNDTR(DMA1_BASE, 1));
    DMA_LIFCR(DMA1_BASE) = 0xFFFFFFFFu;
}

static void timer_update_dma(void)
{
    pin_af(PORT_D, 12, 2);
    RCC_APB1ENR |= RCC_APB1ENR_TIM4EN;
    TIM_CCMR1(TIM4_BASE) = TIM_CCMR_PWM1 | TIM_CCMR_OCPE;
    TIM_CCER(TIM4_BASE) = TIM_CCER_E(1);
    TIM_CCR(TIM4_BASE, 1) = 0;
    TIM_DIER(TIM4_BASE) = TIM_DIER_UDE;
    DMA_SPAR(DMA1_BASE, 6) = (uint32_t)&TIM_CCR(TIM4_BASE, 1);
    DMA_SM0AR(DMA1_BASE, 6) = (uint32_t)table;
    DMA_SNDTR(DMA1_BASE, 6) = 8u;
    DMA_SCR(DMA1_BASE, 6) = CR_CHSEL(2u) | CR_M2P | CR_CIRC | CR_MINC | CR_PSIZE(1u) | CR_MSIZE(1u) | CR_TCIE | CR_HTIE;
    DMA_SCR(DMA1_BASE, 6) |= CR_EN;
    nvic_enable(DMA1_STREAM6_IRQ);
    timer_start(TIM4_BASE, TIM4_PSC, TIM4_ARR, TIM_CR1_ARPE); /* UG: the first request */
    while (rounds < 2) {
        __asm volatile("wfi");
    }
    report("tim_rounds", rounds);
    report("tim_halves", halves);
    report("tim_ccr1", TIM_CCR(TIM4_BASE, 1));
    report("tim_ndtr", DMA_SNDTR(DMA1_BASE, 6)); /* circular: reloaded */
    report("tim_cr_en", DMA_SCR(DMA1_BASE, 6) & CR_EN);
    DMA_SCR(DMA1_BASE, 6) &= ~CR_EN;
}

/* HAL_I2C_Mem_Read_DMA's sequence: the stream armed, the register address written by polling, the read
   address acknowledged, then LAST and DMAEN before ADDR clears; the STOP from the DMA's complete interrupt */
static volatile uint32_t i2c_dma_done;

void dma1_stream0_handler(void)
{
    uint32_t flags = DMA_LISR(DMA1_BASE) & FLAGS;
    DMA_LIFCR(DMA1_BASE) = flags;
    if (flags & FLAG_TCIF) {
        I2C1_CR1 |= I2C_CR1_STOP;
        I2C1_CR2 &= ~(I2C_CR2_DMAEN | I2C_CR2_LAST);
        i2c_dma_done = 1;
    }
}

static void i2c_dma_read(uint8_t *rx, unsigned n)
{
    const uint8_t first = MPU_ACCEL_XOUT_H;
    DMA_SPAR(DMA1_BASE, 0) = (uint32_t)&I2C1_DR;
    DMA_SM0AR(DMA1_BASE, 0) = (uint32_t)rx;
    DMA_SNDTR(DMA1_BASE, 0) = n;
    DMA_SCR(DMA1_BASE, 0) = CR_CHSEL(1u) | CR_MINC | CR_TCIE | CR_TEIE;
    DMA_SCR(DMA1_BASE, 0) |= CR_EN;
    nvic_enable(DMA1_STREAM0_IRQ);
    wait_bus_free();
    I2C1_CR1 &= ~I2C_CR1_POS;
    address(MPU_ADDR << 1);
    clear_addr(&sr1_addr_write, &sr2_addr_write);
    wait_sr1(I2C_SR1_TXE, "stuck_txe_dma");
    I2C1_DR = first;
    wait_sr1(I2C_SR1_BTF, "stuck_btf_dma");
    I2C1_CR1 |= I2C_CR1_ACK;
    address(MPU_ADDR << 1 | 1u);
    I2C1_CR2 |= I2C_CR2_LAST | I2C_CR2_DMAEN;
    clear_addr(&sr1_addr_read, &sr2_addr_read);
    while (!i2c_dma_done) {
        __asm volatile("wfi");
    }
    wait_bus_free();
}

static void i2c_dma(void)
{
    uint8_t polled[14], by_dma[16];
    const uint8_t first = MPU_ACCEL_XOUT_H;
    i2c1_init(I2C_CCR_FS | 14u, 6u); /* 16 MHz / (3 * 14): 381 kHz */
    write_reg(MPU_ADDR, MPU_PWR_MGMT_1, 0x00);
    report("polled_result", (uint32_t)xfer(MPU_ADDR, &first, 1, polled, sizeof polled));
    for (unsigned i = 0; i < sizeof by_dma; i++) {
        by_dma[i] = 0xEE;
    }
    i2c_dma_read(by_dma, 14);
    uint32_t differ = 0;
    for (unsigned i = 0; i < 14; i++) {
        differ += polled[i] != by_dma[i];
    }
    report("polled_0", big_endian(polled, 4));
    report("polled_1", big_endian(polled + 4, 4));
    report("polled_2", big_endian(polled + 8, 4));
    report("polled_3", big_endian(polled + 12, 2));
    report("dma_0", big_endian(by_dma, 4));
    report("dma_1", big_endian(by_dma + 4, 4));
    report("dma_2", big_endian(by_dma + 8, 4));
    report("dma_3", big_endian(by_dma + 12, 2));
    report("dma_after", big_endian(by_dma + 14, 2)); /* untouched: 0xEEEE */
    report("dma_differ", differ);
    report("dma_i2c_ndtr", DMA_SNDTR(DMA1_BASE, 0));
    report("dma_i2c_cr_en", DMA_SCR(DMA1_BASE, 0) & CR_EN);
    report("i2c_sr1_after_dma", I2C1_SR1); /* the last byte NACKed: nothing more came */
    report("who_am_i_after_dma", read_reg(MPU_ADDR, MPU_WHO_AM_I));
}

/* A write by DMA (HAL_I2C_Master_Transmit_DMA's order: DMAEN, then ADDR cleared; TXE's requests give
   DR the register address and its value; after TC, BTF then STOP): the MPU-6050's SMPLRT_DIV, read back
   by polling */
#define MPU_SMPLRT_DIV 0x19u
static void i2c_dma_write(void)
{
    static const uint8_t bytes[2] = { MPU_SMPLRT_DIV, 0x07u };
    DMA_SPAR(DMA1_BASE, 7) = (uint32_t)&I2C1_DR;
    DMA_SM0AR(DMA1_BASE, 7) = (uint32_t)bytes;
    DMA_SNDTR(DMA1_BASE, 7) = 2u;
    DMA_SCR(DMA1_BASE, 7) = CR_CHSEL(1u) | CR_M2P | CR_MINC;
    DMA_SCR(DMA1_BASE, 7) |= CR_EN;
    report("smplrt_div_before", read_reg(MPU_ADDR, MPU_SMPLRT_DIV));
    wait_bus_free();
    address(MPU_ADDR << 1);
    I2C1_CR2 |= I2C_CR2_DMAEN;
    clear_addr(&sr1_addr_write, &sr2_addr_write);
    for (uint32_t i = 0; i < POLL_LIMIT && !(DMA_HISR(DMA1_BASE) & FLAG_TCIF << 22); i++) {
    }
    report("dma_write_hisr", DMA_HISR(DMA1_BASE)); /* stream 7: bits 22-27 */
    DMA_HIFCR(DMA1_BASE) = 0xFFFFFFFFu;
    I2C1_CR2 &= ~I2C_CR2_DMAEN;
    wait_sr1(I2C_SR1_BTF, "stuck_btf_dma_write");
    I2C1_CR1 |= I2C_CR1_STOP;
    report("smplrt_div_after", read_reg(MPU_ADDR, MPU_SMPLRT_DIV));
}

int main(void)
{
    registers();
    memory_to_memory();
    timer_update_dma();
    timer_burst_dma();
    double_buffer_mode();
    request_storm();
    peripheral_transfer_error();
    i2c_dma();
    i2c_dma_write();
    put_text("done\n");
    return 0;
}
