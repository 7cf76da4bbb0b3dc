/* The ADC test firmware of the STM32 tier (tests/stm32/test_adc.py judges its reports against RM0090
   section 13), at the reset clock (16 MHz HSI, PCLK2 16 MHz): the ADCs' registers at reset, without their
   clock and with all ones written; single conversions of ADC1 channel 10 (PC0), 11 and 12 (the volts the
   rig sets through the link) at 12, 10, 8 and 6 bits and left aligned; each conversion's time by
   DWT_CYCCNT for two sampling times and two ADC prescalers; a scan of channels 10, 11, 12 by DMA2 stream 0
   into a circular buffer in continuous mode (Betaflight's pattern), its transfer-complete interrupts
   counted over a window; overruns (EOCS, and DMA with no stream, DR not read); continuous conversions
   nobody reads; the analog watchdog; an injected
   pair with an offset; the internal channels (temperature, VREFINT, VBAT); the EOC interrupt. */
#include "semihost.h"
#include "stm32f405.h"

/* RM0090 13.13 (ADC registers) and table 10 (addresses) */
#define ADC_BASE(n) (0x40012000u + 0x100u * ((n)-1u))
#define ADC_SR(n) REG(ADC_BASE(n) + 0x00u)
#define ADC_CR1(n) REG(ADC_BASE(n) + 0x04u)
#define ADC_CR2(n) REG(ADC_BASE(n) + 0x08u)
#define ADC_SMPR1(n) REG(ADC_BASE(n) + 0x0Cu)
#define ADC_SMPR2(n) REG(ADC_BASE(n) + 0x10u)
#define ADC_JOFR1(n) REG(ADC_BASE(n) + 0x14u)
#define ADC_HTR(n) REG(ADC_BASE(n) + 0x24u)
#define ADC_LTR(n) REG(ADC_BASE(n) + 0x28u)
#define ADC_SQR1(n) REG(ADC_BASE(n) + 0x2Cu)
#define ADC_SQR2(n) REG(ADC_BASE(n) + 0x30u)
#define ADC_SQR3(n) REG(ADC_BASE(n) + 0x34u)
#define ADC_JSQR(n) REG(ADC_BASE(n) + 0x38u)
#define ADC_JDR(n, k) REG(ADC_BASE(n) + 0x3Cu + 4u * ((k)-1u))
#define ADC_DR(n) REG(ADC_BASE(n) + 0x4Cu)
#define ADC_CSR REG(0x40012300u)
#define ADC_CCR REG(0x40012304u)
#define ADC_CDR REG(0x40012308u)
#define SR_EOC (1u << 1)
#define SR_JEOC (1u << 2)
#define SR_OVR (1u << 5)
#define CR1_EOCIE (1u << 5)
#define CR1_SCAN (1u << 8)
#define CR1_AWDSGL (1u << 9)
#define CR1_AWDEN (1u << 23)
#define CR1_RES(n) ((uint32_t)(n) << 24)
#define CR2_ADON (1u << 0)
#define CR2_CONT (1u << 1)
#define CR2_DMA (1u << 8)
#define CR2_DDS (1u << 9)
#define CR2_EOCS (1u << 10)
#define CR2_ALIGN (1u << 11)
#define CR2_JSWSTART (1u << 22)
#define CR2_SWSTART (1u << 30)
#define CCR_ADCPRE(n) ((uint32_t)(n) << 16)
#define CCR_VBATE (1u << 22)
#define CCR_TSVREFE (1u << 23)
#define RCC_APB2ENR_ADCEN (7u << 8) /* ADC1EN, ADC2EN, ADC3EN */
#define ADC_IRQ 18u

/* RM0090 10.5: DMA2 stream 0 */
#define DMA2_LISR REG(0x40026400u)
#define DMA2_LIFCR REG(0x40026408u)
#define DMA2_S0CR REG(0x40026410u)
#define DMA2_S0NDTR REG(0x40026414u)
#define DMA2_S0PAR REG(0x40026418u)
#define DMA2_S0M0AR REG(0x4002641Cu)
#define RCC_AHB1ENR_DMA2EN (1u << 22)
#define DMA_EN (1u << 0)
#define DMA_TCIE (1u << 4)
#define DMA_CIRC (1u << 8)
#define DMA_MINC (1u << 10)
#define DMA_HALFWORDS ((1u << 11) | (1u << 13)) /* PSIZE, MSIZE 16 bits */
#define DMA2_STREAM0_IRQ 56u
#define SCAN_WINDOW_CYCLES 295200u

static volatile uint16_t scan[3];
static volatile uint32_t scan_rounds, eoc_interrupts, eoc_value;

void dma2_stream0_handler(void);
void dma2_stream0_handler(void)
{
    DMA2_LIFCR = 0x3Du; /* stream 0's flags */
    scan_rounds++;
}

void adc_handler(void);
void adc_handler(void)
{
    eoc_value = ADC_DR(1); /* (clears EOC: the line goes down) */
    eoc_interrupts++;
}

static void report_n(const char *prefix, unsigned n, uint32_t value)
{
    char name[32];
    unsigned i = 0;
    while (*prefix && i < sizeof name - 3) {
        name[i++] = *prefix++;
    }
    name[i++] = (char)('0' + n / 10u);
    name[i++] = (char)('0' + n % 10u);
    name[i] = '\0';
    report(name, value);
}

static void wait_cycles(uint32_t cycles)
{
    uint32_t start = DWT_CYCCNT;
    while (DWT_CYCCNT - start < cycles) {
    }
}

/* One regular conversion of ADC1 @channel: DR */
static uint32_t convert(unsigned channel)
{
    ADC_SQR1(1) = 0;
    ADC_SQR3(1) = channel;
    ADC_CR2(1) |= CR2_SWSTART;
    while (!(ADC_SR(1) & SR_EOC)) {
    }
    return ADC_DR(1);
}

static void registers(void)
{
    ADC_CR1(1) = 0xFFFFFFFFu; /* no clock: lost */
    report("cr1_unclocked", ADC_CR1(1));
    RCC_APB2ENR |= RCC_APB2ENR_ADCEN;
    uint32_t any = 0;
    for (unsigned n = 1; n <= 3; n++) {
        for (uint32_t off = 0; off <= 0x4Cu; off += 4u) {
            if (off != 0x24u) {
                any |= REG(ADC_BASE(n) + off);
            }
        }
    }
    report("or_of_reset", any | ADC_CSR | ADC_CCR | ADC_CDR);
    report("htr_reset", ADC_HTR(2));
    static const uint8_t offsets[] = { 0x04, 0x0C, 0x10, 0x14, 0x24, 0x28, 0x2C, 0x30, 0x34, 0x38, 0x3C, 0x4C };
    for (unsigned i = 0; i < sizeof offsets; i++) {
        REG(ADC_BASE(2) + offsets[i]) = 0xFFFFFFFFu;
        report_n("ones_", offsets[i], REG(ADC_BASE(2) + offsets[i]));
        REG(ADC_BASE(2) + offsets[i]) = 0;
    }
    ADC_CR2(2) = 0xFFFFFFFFu & ~CR2_JSWSTART; /* ADON and SWSTART: a conversion starts at once */
    report("ones_cr2", ADC_CR2(2));
    ADC_CR2(2) = 0;
    ADC_SR(2) = 0;
    ADC_CCR = 0x00C3EF00u; /* all but MULTI (multi mode is not modelled) */
    report("ccr_ones", ADC_CCR);
    ADC_CCR = 0;
}

static void single(void)
{
    ADC_SMPR1(1) = 7u << 0 | 7u << 3 | 7u << 6; /* channels 10-12: 480 cycles */
    for (unsigned res = 0; res < 4; res++) {
        ADC_CR1(1) = CR1_RES(res);
        ADC_CR2(1) = CR2_ADON;
        report_n("ch10_res", res, convert(10));
    }
    ADC_CR1(1) = 0;
    report("ch11", convert(11));
    report("ch12", convert(12));
    report("ch0", convert(0));
    report("sr_after", ADC_SR(1));
    ADC_CR2(1) = CR2_ADON | CR2_ALIGN;
    report("ch10_left", convert(10));
    ADC_CR1(1) = CR1_RES(3);
    report("ch10_left6", convert(10));
    ADC_CR1(1) = 0;
    ADC_CR2(1) = CR2_ADON;
}

/* Cycles from SWSTART to EOC seen, for channel 10's SMP @smp at ADCPRE @pre */
static uint32_t timed(unsigned smp, unsigned pre)
{
    ADC_CCR = CCR_ADCPRE(pre);
    ADC_SMPR1(1) = smp;
    ADC_SQR3(1) = 10;
    uint32_t start = DWT_CYCCNT;
    ADC_CR2(1) = CR2_ADON | CR2_SWSTART;
    while (!(ADC_SR(1) & SR_EOC)) {
    }
    uint32_t cycles = DWT_CYCCNT - start;
    (void)ADC_DR(1);
    return cycles;
}

static void timing(void)
{
    report("time_smp0_pre0", timed(0, 0));
    report("time_smp7_pre0", timed(7, 0));
    report("time_smp0_pre3", timed(0, 3));
    report("time_smp7_pre3", timed(7, 3));
    report("time_smp4_pre1", timed(4, 1));
    uint32_t start = DWT_CYCCNT;
    for (unsigned i = 0; i < 100u; i++) {
        (void)ADC_SR(1);
    }
    report("poll_100", DWT_CYCCNT - start);
    ADC_CCR = 0;
}

static void scan_by_dma(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_DMA2EN;
    DMA2_S0PAR = ADC_BASE(1) + 0x4Cu;
    DMA2_S0M0AR = (uint32_t)(uintptr_t)scan;
    DMA2_S0NDTR = 3;
    DMA2_S0CR = DMA_HALFWORDS | DMA_MINC | DMA_CIRC | DMA_TCIE; /* channel 0, peripheral to memory */
    DMA2_S0CR |= DMA_EN;
    NVIC_ISER(DMA2_STREAM0_IRQ / 32u) = 1u << (DMA2_STREAM0_IRQ % 32u);
    ADC_SMPR1(1) = 7u << 0 | 7u << 3 | 7u << 6;
    ADC_CR1(1) = CR1_SCAN;
    ADC_SQR1(1) = 2u << 20; /* three conversions */
    ADC_SQR3(1) = 10u | 11u << 5 | 12u << 10;
    uint32_t start = DWT_CYCCNT;
    ADC_CR2(1) = CR2_ADON | CR2_CONT | CR2_DMA | CR2_DDS | CR2_SWSTART;
    while (DWT_CYCCNT - start < SCAN_WINDOW_CYCLES) {
    }
    report("scan_rounds", scan_rounds);
    report("scan_0", scan[0]);
    report("scan_1", scan[1]);
    report("scan_2", scan[2]);
    report("scan_ndtr", DMA2_S0NDTR);
    report("scan_sr", ADC_SR(1));
    ADC_CR2(1) = 0;
    DMA2_S0CR &= ~DMA_EN;
    ADC_SR(1) = 0;
    ADC_CR1(1) = 0;
    ADC_SQR1(1) = 0;
}

static void overrun(void)
{
    ADC_SMPR1(1) = 0;
    ADC_SQR3(1) = 10;
    ADC_CR2(1) = CR2_ADON | CR2_CONT | CR2_EOCS | CR2_SWSTART;
    wait_cycles(1000); /* 30 cycles a conversion */
    report("ovr_sr", ADC_SR(1));
    report("ovr_dr", ADC_DR(1));
    ADC_CR2(1) = CR2_ADON | CR2_SWSTART; /* ignored while OVR is set */
    wait_cycles(100);
    report("ovr_sr_ignored", ADC_SR(1));
    ADC_SR(1) = 0;
    report("ovr_cleared", convert(11));
    /* with DMA and no stream to take DR: the second conversion overruns */
    ADC_CR2(1) = CR2_ADON | CR2_CONT | CR2_DMA | CR2_SWSTART;
    wait_cycles(1000);
    report("ovr_dma_sr", ADC_SR(1));
    ADC_CR2(1) = CR2_ADON;
    ADC_SR(1) = 0;
    /* without DMA and with EOCS = 0 no overrun is detected: conversions go on unread */
    ADC_SQR3(1) = 10;
    ADC_CR2(1) = CR2_ADON | CR2_CONT | CR2_SWSTART;
    wait_cycles(200000);
    report("cont_sr", ADC_SR(1));
    report("cont_dr", ADC_DR(1));
    ADC_CR2(1) = 0;
    ADC_SR(1) = 0;
}

/* The analog watchdog on channel 10 alone, its high threshold under the battery's code */
static void watchdog(void)
{
    ADC_HTR(1) = 1000;
    ADC_LTR(1) = 0;
    ADC_CR1(1) = CR1_AWDEN | CR1_AWDSGL | 10u;
    ADC_CR2(1) = CR2_ADON;
    (void)convert(12);
    report("awd_sr_12", ADC_SR(1));
    (void)convert(10);
    report("awd_sr_10", ADC_SR(1));
    ADC_CR1(1) = 0;
    ADC_SR(1) = 0;
    ADC_HTR(1) = 0xFFF;
}

static void injected(void)
{
    ADC_CR1(1) = CR1_SCAN;
    ADC_JSQR(1) = 1u << 20 | 10u << 10 | 11u << 15; /* JL = 1: JSQ3, JSQ4 */
    ADC_JOFR1(1) = 100;
    ADC_CR2(1) = CR2_ADON | CR2_JSWSTART;
    while (!(ADC_SR(1) & SR_JEOC)) {
    }
    report("jdr1", ADC_JDR(1, 1));
    report("jdr2", ADC_JDR(1, 2));
    ADC_CR1(1) = 0;
    ADC_CR2(1) = CR2_ADON;
    ADC_SR(1) = 0;
}

static void internal(void)
{
    ADC_SMPR1(1) = 7u << 18 | 7u << 21 | 7u << 24; /* channels 16-18: 480 cycles (the sensor needs 10 us) */
    report("ch17_off", convert(17));
    ADC_CCR = CCR_TSVREFE;
    report("ch16_temp", convert(16));
    report("ch17_vrefint", convert(17));
    report("ch18_no_vbate", convert(18));
    ADC_CCR = CCR_VBATE;
    report("ch18_vbat", convert(18));
    ADC_CCR = 0;
}

static void interrupt(void)
{
    NVIC_ISER(0) = 1u << ADC_IRQ;
    ADC_CR1(1) = CR1_EOCIE;
    ADC_SQR3(1) = 10;
    ADC_CR2(1) = CR2_ADON | CR2_SWSTART;
    while (eoc_interrupts == 0) {
        __asm volatile("wfi");
    }
    wait_cycles(1000);
    report("eoc_interrupts", eoc_interrupts);
    report("eoc_value", eoc_value);
    ADC_CR1(1) = 0;
}

int main(void)
{
    DWT_CTRL |= 1u;
    registers();
    single();
    timing();
    scan_by_dma();
    overrun();
    watchdog();
    injected();
    internal();
    interrupt();
    put_text("done\n");
    exit_with(0);
    return 0;
}
