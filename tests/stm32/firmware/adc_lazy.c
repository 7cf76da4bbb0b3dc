/* The ADC's lazy DMA scan (tests/stm32/test_adc_lazy.py runs it with the ADC model eager and lazy, the
   rig changing channel 11's volts at every 1 ms stop): at the reset clock (16 MHz, ADCPRE /2: an 8 MHz
   ADC clock), ADC1 scans channels 10, 11, 12 at 480 cycles (61.5 us, 984 CPU cycles a conversion) again and
   again into a circular buffer of two sequences by DMA2 stream 0, as Betaflight reads its battery and
   current. First with no interrupt: the buffer copied every SAMPLE_CYCLES with no register access (the
   memory as the core sees it between catch-ups), and every fourth time the stream's flags and NDTR too
   (the flags then cleared); then with HTIE and TCIE, each interrupt's cycle, flags, NDTR and buffer; then
   into a buffer of ROTATING items, no whole number of sequences (each round puts other channels at each
   place), copied every SAMPLE_CYCLES with no register access. */
#include "semihost.h"
#include "stm32f405.h"

/* RM0090 13.13 (ADC registers) and table 10 (addresses) */
#define ADC1_CR1 REG(0x40012004u)
#define ADC1_CR2 REG(0x40012008u)
#define ADC1_SMPR1 REG(0x4001200Cu)
#define ADC1_SQR1 REG(0x4001202Cu)
#define ADC1_SQR3 REG(0x40012034u)
#define ADC1_DR_ADDR 0x4001204Cu
#define CR1_SCAN (1u << 8)
#define CR2_ADON (1u << 0)
#define CR2_CONT (1u << 1)
#define CR2_DMA (1u << 8)
#define CR2_DDS (1u << 9)
#define CR2_SWSTART (1u << 30)
#define RCC_APB2ENR_ADC1EN (1u << 8)

/* RM0090 10.5: DMA2 stream 0 (channel 0: ADC1, table 43) */
#define DMA2_LISR REG(0x40026400u)
#define DMA2_LIFCR REG(0x40026408u)
#define DMA2_S0CR REG(0x40026410u)
#define DMA2_S0NDTR REG(0x40026414u)
#define DMA2_S0PAR REG(0x40026418u)
#define DMA2_S0M0AR REG(0x4002641Cu)
#define RCC_AHB1ENR_DMA2EN (1u << 22)
#define DMA_EN (1u << 0)
#define DMA_HTIE (1u << 3)
#define DMA_TCIE (1u << 4)
#define DMA_CIRC (1u << 8)
#define DMA_MINC (1u << 10)
#define DMA_HALFWORDS ((1u << 11) | (1u << 13)) /* PSIZE, MSIZE 16 bits */
#define STREAM0_FLAGS 0x3Du
#define DMA2_STREAM0_IRQ 56u

#define ITEMS 6u /* two sequences of three */
#define SAMPLES 48u
#define SAMPLE_CYCLES 2500u /* (no multiple of a conversion's 984: the samples fall at every phase) */
#define INTERRUPTS 12u
#define ROTATING 4u
#define ROTATING_SAMPLES 16u

static volatile uint16_t buffer[ITEMS];
static uint16_t samples[SAMPLES][ITEMS];
static uint32_t sample_lisr[SAMPLES], sample_ndtr[SAMPLES];
static volatile uint32_t interrupts;
static uint32_t irq_cycle[INTERRUPTS], irq_lisr[INTERRUPTS], irq_ndtr[INTERRUPTS];
static uint16_t irq_buffer[INTERRUPTS][ITEMS];
static uint16_t rotating[ROTATING_SAMPLES][ROTATING];

void dma2_stream0_handler(void);
void dma2_stream0_handler(void)
{
    uint32_t cycle = DWT_CYCCNT, k = interrupts;
    if (k < INTERRUPTS) {
        irq_cycle[k] = cycle;
        irq_lisr[k] = DMA2_LISR & STREAM0_FLAGS;
        irq_ndtr[k] = DMA2_S0NDTR;
        for (unsigned i = 0; i < ITEMS; i++) {
            irq_buffer[k][i] = buffer[i];
        }
    }
    DMA2_LIFCR = STREAM0_FLAGS;
    interrupts = k + 1;
}

/* @name@k@_@i as a report's name */
static void report_at(const char *name, unsigned k, unsigned i, uint32_t value)
{
    char text[24];
    unsigned n = 0;
    while (*name && n < sizeof text - 8) {
        text[n++] = *name++;
    }
    text[n++] = (char)('0' + k / 10u);
    text[n++] = (char)('0' + k % 10u);
    text[n++] = '_';
    text[n++] = (char)('0' + i);
    text[n] = '\0';
    report(text, value);
}

int main(void)
{
    DWT_CTRL |= 1u;
    RCC_AHB1ENR |= RCC_AHB1ENR_DMA2EN;
    RCC_APB2ENR |= RCC_APB2ENR_ADC1EN;
    DMA2_S0PAR = ADC1_DR_ADDR;
    DMA2_S0M0AR = (uint32_t)(uintptr_t)buffer;
    DMA2_S0NDTR = ITEMS;
    DMA2_S0CR = DMA_HALFWORDS | DMA_MINC | DMA_CIRC;
    DMA2_S0CR |= DMA_EN;
    ADC1_SMPR1 = 7u << 0 | 7u << 3 | 7u << 6; /* channels 10-12: 480 cycles */
    ADC1_CR1 = CR1_SCAN;
    ADC1_SQR1 = 2u << 20; /* three conversions */
    ADC1_SQR3 = 10u | 11u << 5 | 12u << 10;
    uint32_t start = DWT_CYCCNT;
    ADC1_CR2 = CR2_ADON | CR2_CONT | CR2_DMA | CR2_DDS | CR2_SWSTART;
    for (unsigned k = 0; k < SAMPLES; k++) {
        while (DWT_CYCCNT - start < (k + 1u) * SAMPLE_CYCLES) {
        }
        if (k % 4u == 3u) {
            sample_lisr[k] = DMA2_LISR & STREAM0_FLAGS;
            sample_ndtr[k] = DMA2_S0NDTR;
            DMA2_LIFCR = STREAM0_FLAGS;
        }
        for (unsigned i = 0; i < ITEMS; i++) {
            samples[k][i] = buffer[i];
        }
    }
    DMA2_LIFCR = STREAM0_FLAGS;
    NVIC_ISER(DMA2_STREAM0_IRQ / 32u) = 1u << (DMA2_STREAM0_IRQ % 32u);
    DMA2_S0CR |= DMA_HTIE | DMA_TCIE; /* (writable while the stream runs) */
    while (interrupts < INTERRUPTS) {
        __asm volatile("wfi");
    }
    ADC1_CR2 = 0;
    DMA2_S0CR &= ~DMA_EN;
    NVIC_ICER(DMA2_STREAM0_IRQ / 32u) = 1u << (DMA2_STREAM0_IRQ % 32u);
    DMA2_LIFCR = STREAM0_FLAGS;
    DMA2_S0NDTR = ROTATING;
    DMA2_S0CR = DMA_HALFWORDS | DMA_MINC | DMA_CIRC;
    DMA2_S0CR |= DMA_EN;
    start = DWT_CYCCNT;
    ADC1_CR2 = CR2_ADON | CR2_CONT | CR2_DMA | CR2_DDS | CR2_SWSTART;
    for (unsigned k = 0; k < ROTATING_SAMPLES; k++) {
        while (DWT_CYCCNT - start < (k + 1u) * SAMPLE_CYCLES) {
        }
        for (unsigned i = 0; i < ROTATING; i++) {
            rotating[k][i] = buffer[i];
        }
    }
    ADC1_CR2 = 0;
    DMA2_S0CR &= ~DMA_EN;
    for (unsigned k = 0; k < SAMPLES; k++) {
        for (unsigned i = 0; i < ITEMS; i++) {
            report_at("sample", k, i, samples[k][i]);
        }
        if (k % 4u == 3u) {
            report_at("sample", k, 6, sample_lisr[k]);
            report_at("sample", k, 7, sample_ndtr[k]);
        }
    }
    for (unsigned k = 0; k < INTERRUPTS; k++) {
        for (unsigned i = 0; i < ITEMS; i++) {
            report_at("irq", k, i, irq_buffer[k][i]);
        }
        report_at("irq", k, 6, irq_lisr[k]);
        report_at("irq", k, 7, irq_ndtr[k]);
        report_at("irq", k, 8, irq_cycle[k]);
    }
    for (unsigned k = 0; k < ROTATING_SAMPLES; k++) {
        for (unsigned i = 0; i < ROTATING; i++) {
            report_at("rotating", k, i, rotating[k][i]);
        }
    }
    put_text("done\n");
    exit_with(0);
    return 0;
}
