/*
 * The STM32F405's reset and clock control (RCC), RM0090 section 7.3, and the STM32F411's (RM0383 section
 * 6.3: the same clock tree and registers, fewer enable bits; the "chip" property picks the table).
 *
 * What start-up code waits for: each oscillator's ready flag follows its enable (HSIRDY after HSION,
 * HSERDY after HSEON, PLLRDY after PLLON, PLLI2SRDY, LSERDY, LSIRDY), at once: the ready time of a
 * real crystal is not modelled. The system clock switch (CFGR.SWS) follows CFGR.SW when the selected
 * source is ready, and later when it becomes ready, as the hardware does; an oscillator that feeds the
 * system clock cannot be stopped. The AHB clock (HCLK = SYSCLK / HPRE) is the "hclk" clock output,
 * which drives the core, SysTick and DWT: a firmware that sets up 168 MHz runs SysTick at 168 MHz. The
 * timers' clocks ("apb1-tim", "apb2-tim") are PCLK1 = HCLK / PPRE1 and PCLK2 = HCLK / PPRE2, doubled when
 * the prescaler is not 1 (RM0090 figure 21): 84 and 168 MHz under ST's 168 MHz set-up; on the F411 with
 * DCKCFGR.TIMPRE set, HCLK when the prescaler is 1, 2 or 4, else four times PCLKx (RM0383 6.3.23).
 * The reset registers reset the peripherals the machine attached to their bits (GPIO ports, PWR).
 * CSR's reset flags survive a system reset (a watchdog's sets its own: IWDGRSTF, WWDGRSTF).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#include "qemu/osdep.h"

#include "hw/qdev-clock.h"
#include "hw/qdev-properties.h"
#include "qapi/error.h"
#include "qemu/log.h"
#include "qemu/module.h"
#include "rig_stm32f4.h"
#include "sysemu/runstate.h"

#define HSI_HZ 16000000u

/* RCC_CR */
#define CR_HSION (1u << 0)
#define CR_HSIRDY (1u << 1)
#define CR_HSEON (1u << 16)
#define CR_HSERDY (1u << 17)
#define CR_PLLON (1u << 24)
#define CR_PLLRDY (1u << 25)
#define CR_PLLI2SON (1u << 26)
#define CR_PLLI2SRDY (1u << 27)
/* RCC_CFGR */
#define CFGR_SW_MASK 0x3u
#define CFGR_SWS_SHIFT 2
#define CFGR_SWS_MASK (0x3u << CFGR_SWS_SHIFT)
#define SW_HSI 0u
#define SW_HSE 1u
#define SW_PLL 2u
/* RCC_PLLCFGR */
#define PLLCFGR_SRC_HSE (1u << 22)
/* RCC_BDCR, RCC_CSR */
#define BDCR_LSEON (1u << 0)
#define BDCR_LSERDY (1u << 1)
#define CSR_LSION (1u << 0)
#define CSR_LSIRDY (1u << 1)
#define CSR_RMVF (1u << 24)
#define CSR_RESET_FLAGS 0xFE000000u
#define CSR_PINRSTF (1u << 26)
#define CSR_SFTRSTF (1u << 28)

/*
 * RM0090 rev 19, table 34 (RCC register map and reset values) for the STM32F405/407; the writable
 * masks are the bits each register's description marks rw.
 */
static const RigRegister rcc_f405[] = {
    { 0x00, "CR", 0x00000083, 0x050D00F9 }, /* HSITRIM = 16, HSION, HSIRDY */
    { 0x04, "PLLCFGR", 0x24003010, 0x0F437FFF },   { 0x08, "CFGR", 0x00000000, 0xFFFFFCF3 },
    { 0x0C, "CIR", 0x00000000, 0x00003F00 },       { 0x10, "AHB1RSTR", 0x00000000, 0x226011FF },
    { 0x14, "AHB2RSTR", 0x00000000, 0x000000F1 },  { 0x18, "AHB3RSTR", 0x00000000, 0x00000001 },
    { 0x20, "APB1RSTR", 0x00000000, 0x36FEC9FF },  { 0x24, "APB2RSTR", 0x00000000, 0x00075933 },
    { 0x30, "AHB1ENR", 0x00100000, 0x7E7411FF },   { 0x34, "AHB2ENR", 0x00000000, 0x000000F1 },
    { 0x38, "AHB3ENR", 0x00000000, 0x00000001 },   { 0x40, "APB1ENR", 0x00000000, 0x36FEC9FF },
    { 0x44, "APB2ENR", 0x00000000, 0x00075F33 },   { 0x50, "AHB1LPENR", 0x7E6791FF, 0x7E6791FF },
    { 0x54, "AHB2LPENR", 0x000000F1, 0x000000F1 }, { 0x58, "AHB3LPENR", 0x00000001, 0x00000001 },
    { 0x60, "APB1LPENR", 0x36FEC9FF, 0x36FEC9FF }, { 0x64, "APB2LPENR", 0x00075F33, 0x00075F33 },
    { 0x70, "BDCR", 0x00000000, 0x00018305 },      { 0x74, "CSR", 0x0E000000, 0x00000001 },
    { 0x80, "SSCGR", 0x00000000, 0xCFFFFFFF },     { 0x84, "PLLI2SCFGR", 0x20003000, 0x70007FC0 },
};

/*
 * RM0383 section 6.3 (the RCC register map and reset values) for the STM32F411xC/E: no AHB3 (no FSMC),
 * fewer clock enables (GPIOA-E and H, CRC, DMA1/2; TIM1-5, TIM9-11, USART1/2/6, I2C1-3, SPI1-5, SDIO,
 * ADC1, WWDG, PWR, SYSCFG, OTG FS), no CCM RAM clock (AHB1ENR resets to 0), PLLI2SM in PLLI2SCFGR, and
 * DCKCFGR's TIMPRE. The same registers in the same order as the F405's up to PLLI2SCFGR (the R_ indexes
 * below hold for both); the low-power enables' reset values are the manual's (TIM1 and SPI5 not set).
 */
static const RigRegister rcc_f411[] = {
    { 0x00, "CR", 0x00000083, 0x050D00F9 },        { 0x04, "PLLCFGR", 0x24003010, 0x0F437FFF },
    { 0x08, "CFGR", 0x00000000, 0xFFFFFCF3 },      { 0x0C, "CIR", 0x00000000, 0x00003F00 },
    { 0x10, "AHB1RSTR", 0x00000000, 0x0060109F },  { 0x14, "AHB2RSTR", 0x00000000, 0x00000080 },
    { 0x20, "APB1RSTR", 0x00000000, 0x10E2C80F },  { 0x24, "APB2RSTR", 0x00000000, 0x00177931 },
    { 0x30, "AHB1ENR", 0x00000000, 0x0060109F },   { 0x34, "AHB2ENR", 0x00000000, 0x00000080 },
    { 0x40, "APB1ENR", 0x00000000, 0x10E2C80F },   { 0x44, "APB2ENR", 0x00000000, 0x00177931 },
    { 0x50, "AHB1LPENR", 0x0061900F, 0x0061909F }, { 0x54, "AHB2LPENR", 0x00000080, 0x00000080 },
    { 0x60, "APB1LPENR", 0x10E2C80F, 0x10E2C80F }, { 0x64, "APB2LPENR", 0x00077930, 0x00177931 },
    { 0x70, "BDCR", 0x00000000, 0x00018305 },      { 0x74, "CSR", 0x0E000000, 0x00000001 },
    { 0x80, "SSCGR", 0x00000000, 0xCFFFFFFF },     { 0x84, "PLLI2SCFGR", 0x24003000, 0x70007FFF },
    { 0x8C, "DCKCFGR", 0x00000000, 0x01000000 },
};

/* the indexes of the first registers, the same in both tables; BDCR and CSR are found by offset */
enum { R_CR = 0, R_PLLCFGR = 1, R_CFGR = 2 };
#define BDCR 0x70
#define CSR 0x74

int rig_register_index(const RigRegister *table, int count, hwaddr offset)
{
    for (int i = 0; i < count; i++) {
        if (table[i].offset == offset) {
            return i;
        }
    }
    return -1;
}

/* RCC_CSR (its place differs between the chips' tables) */
static uint32_t *rcc_csr(RigStm32RccState *s) { return &s->regs[rig_register_index(s->table, s->count, CSR)]; }

bool rig_stm32_rcc_enabled(RigStm32RccState *rcc, hwaddr enr_offset, unsigned bit)
{
    int i = rig_register_index(rcc->table, rcc->count, enr_offset);
    return i >= 0 && (rcc->regs[i] >> bit & 1u);
}

void rig_stm32_rcc_add_reset(RigStm32RccState *rcc, hwaddr rstr_offset, unsigned bit, DeviceState *dev)
{
    assert(rcc->n_resets < RIG_RCC_RESETS);
    rcc->resets[rcc->n_resets].rstr_offset = rstr_offset;
    rcc->resets[rcc->n_resets].bit = bit;
    rcc->resets[rcc->n_resets].dev = dev;
    rcc->n_resets++;
}

/* A peripheral whose reset bit is set is held in reset: reset again at each write that leaves it set */
static void rcc_reset_peripherals(RigStm32RccState *s, hwaddr offset)
{
    for (unsigned k = 0; k < s->n_resets; k++) {
        if (s->resets[k].rstr_offset == offset && rig_stm32_rcc_enabled(s, offset, s->resets[k].bit)) {
            device_cold_reset(s->resets[k].dev);
        }
    }
}

static bool source_ready(const RigStm32RccState *s, unsigned sw)
{
    uint32_t cr = s->regs[R_CR];
    switch (sw) {
    case SW_HSI:
        return cr & CR_HSIRDY;
    case SW_HSE:
        return cr & CR_HSERDY;
    case SW_PLL:
        return cr & CR_PLLRDY;
    default: /* 11: not allowed */
        return false;
    }
}

static uint64_t pll_hz(const RigStm32RccState *s)
{
    uint32_t cfg = s->regs[R_PLLCFGR];
    uint32_t m = cfg & 0x3F, n = cfg >> 6 & 0x1FF, p = 2 * ((cfg >> 16 & 0x3) + 1);
    uint64_t in = (cfg & PLLCFGR_SRC_HSE) ? s->hse_hz : HSI_HZ;
    if (m < 2 || n < 2) { /* PLLM and PLLN below 2 are wrong configurations: no output */
        return 0;
    }
    return in / m * n / p;
}

static uint64_t sysclk_hz(const RigStm32RccState *s)
{
    switch (s->regs[R_CFGR] >> CFGR_SWS_SHIFT & 0x3) {
    case SW_HSE:
        return s->hse_hz;
    case SW_PLL:
        return pll_hz(s);
    default:
        return HSI_HZ;
    }
}

static uint64_t hclk_hz(const RigStm32RccState *s)
{
    /* HPRE: 0xxx: /1; 1000..1111: /2, /4, /8, /16, /64, /128, /256, /512 */
    static const unsigned shift[8] = { 1, 2, 3, 4, 6, 7, 8, 9 };
    unsigned hpre = s->regs[R_CFGR] >> 4 & 0xF;
    uint64_t hz = sysclk_hz(s);
    return (hpre & 0x8) ? hz >> shift[hpre & 0x7] : hz;
}

/* log2 of the APB prescaler's division: PPRE1 (bits 12:10) and PPRE2 (15:13): 0xx: /1; 100..111: /2, /4,
 * /8, /16 */
static unsigned apb_shift(const RigStm32RccState *s, unsigned apb)
{
    unsigned ppre = s->regs[R_CFGR] >> (apb == 1 ? 10 : 13) & 0x7;
    return (ppre & 0x4) ? (ppre & 0x3) + 1 : 0;
}

uint64_t rig_stm32_rcc_pclk_hz(RigStm32RccState *rcc, unsigned apb) { return hclk_hz(rcc) >> apb_shift(rcc, apb); }

/* DCKCFGR.TIMPRE, on a chip whose table has DCKCFGR (the F411: RM0383 6.3.23; the F405 has none) */
#define DCKCFGR 0x8C
#define DCKCFGR_TIMPRE (1u << 24)

uint64_t rig_stm32_rcc_timer_hz(RigStm32RccState *rcc, unsigned apb)
{
    unsigned shift = apb_shift(rcc, apb);
    uint64_t pclk = rig_stm32_rcc_pclk_hz(rcc, apb);
    int dckcfgr = rig_register_index(rcc->table, rcc->count, DCKCFGR);
    if (dckcfgr >= 0 && (rcc->regs[dckcfgr] & DCKCFGR_TIMPRE)) {
        /* TIMPRE: HCLK while the APB prescaler divides by 1, 2 or 4, else four times PCLKx */
        return shift <= 2 ? hclk_hz(rcc) : 4 * pclk;
    }
    /* PCLKx while the APB prescaler divides by 1, else twice PCLKx */
    return shift == 0 ? pclk : 2 * pclk;
}

/* The hardware's side of CR, BDCR, CSR and CFGR.SWS after a write */
static void rcc_settle(RigStm32RccState *s)
{
    uint32_t cr = s->regs[R_CR];
    unsigned sws = s->regs[R_CFGR] >> CFGR_SWS_SHIFT & 0x3;
    /* an oscillator that clocks the system cannot be stopped (RM0090 7.3.1) */
    if (sws == SW_HSI || (sws == SW_PLL && !(s->regs[R_PLLCFGR] & PLLCFGR_SRC_HSE))) {
        cr |= CR_HSION;
    }
    if (sws == SW_HSE || (sws == SW_PLL && (s->regs[R_PLLCFGR] & PLLCFGR_SRC_HSE))) {
        cr |= CR_HSEON;
    }
    if (sws == SW_PLL) {
        cr |= CR_PLLON;
    }
    cr = (cr & ~(CR_HSIRDY | CR_HSERDY | CR_PLLRDY | CR_PLLI2SRDY)) | (cr & CR_HSION ? CR_HSIRDY : 0) |
         (cr & CR_HSEON ? CR_HSERDY : 0) | (cr & CR_PLLON ? CR_PLLRDY : 0) | (cr & CR_PLLI2SON ? CR_PLLI2SRDY : 0);
    s->regs[R_CR] = cr;
    uint32_t *bdcr = &s->regs[rig_register_index(s->table, s->count, BDCR)];
    uint32_t *csr = &s->regs[rig_register_index(s->table, s->count, CSR)];
    *bdcr = (*bdcr & ~BDCR_LSERDY) | (*bdcr & BDCR_LSEON ? BDCR_LSERDY : 0);
    *csr = (*csr & ~CSR_LSIRDY) | (*csr & CSR_LSION ? CSR_LSIRDY : 0);

    unsigned sw = s->regs[R_CFGR] & CFGR_SW_MASK;
    if (sw != sws && source_ready(s, sw)) {
        s->regs[R_CFGR] = (s->regs[R_CFGR] & ~CFGR_SWS_MASK) | sw << CFGR_SWS_SHIFT;
    }
    uint64_t hz = hclk_hz(s);
    if (hz != clock_get_hz(s->hclk)) {
        clock_update_hz(s->hclk, hz);
    }
    for (unsigned apb = 1; apb <= 2; apb++) {
        hz = rig_stm32_rcc_timer_hz(s, apb);
        if (hz != s->tim_hz[apb - 1]) {
            s->tim_hz[apb - 1] = hz;
            clock_update_hz(s->tim_clk[apb - 1], hz);
        }
    }
}

static uint64_t rcc_read(void *opaque, hwaddr offset, unsigned size)
{
    RigStm32RccState *s = opaque;
    int i = rig_register_index(s->table, s->count, offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-rcc: read of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return 0;
    }
    return s->regs[i];
}

static void rcc_write(void *opaque, hwaddr offset, uint64_t value, unsigned size)
{
    RigStm32RccState *s = opaque;
    int i = rig_register_index(s->table, s->count, offset);
    if (i < 0) {
        qemu_log_mask(LOG_GUEST_ERROR, "rig-stm32f4-rcc: write of reserved offset 0x%" HWADDR_PRIx "\n", offset);
        return;
    }
    uint32_t mask = s->table[i].writable;
    if (offset == CSR && (value & CSR_RMVF)) { /* RMVF clears the reset flags */
        s->regs[i] &= ~CSR_RESET_FLAGS;
    }
    s->regs[i] = (s->regs[i] & ~mask) | ((uint32_t)value & mask);
    rcc_settle(s);
    rcc_reset_peripherals(s, offset);
}

static const MemoryRegionOps rcc_ops = {
    .read = rcc_read,
    .write = rcc_write,
    .endianness = DEVICE_NATIVE_ENDIAN,
    .impl.min_access_size = 4,
    .impl.max_access_size = 4,
};

RigResetCause rig_reset_cause;

void rig_stm32_rcc_watchdog_reset(RigStm32RccState *rcc, uint32_t csr_flag, RigResetCause cause)
{
    *rcc_csr(rcc) |= csr_flag;
    rig_reset_cause = cause;
    qemu_system_reset_request(SHUTDOWN_CAUSE_GUEST_RESET);
}

/* A system reset restores every register but CSR's reset flags, which only a power-on reset (or RMVF)
 * clears; the reset pulses NRST whatever its source, so PINRSTF is set too (RM0090 6.1.2, 7.3.21) */
static void rcc_reset(DeviceState *dev)
{
    RigStm32RccState *s = RIG_STM32_RCC(dev);
    uint32_t flags = *rcc_csr(s) & CSR_RESET_FLAGS;
    for (unsigned i = 0; i < s->count; i++) {
        s->regs[i] = s->table[i].reset;
    }
    if (s->powered) {
        /* a reset that is not a watchdog's is the firmware's request (AIRCR.SYSRESETREQ): SFTRSTF */
        uint32_t source = rig_reset_cause == RIG_RESET_SYSTEM ? CSR_SFTRSTF : 0;
        *rcc_csr(s) = (*rcc_csr(s) & ~CSR_RESET_FLAGS) | flags | CSR_PINRSTF | source;
    }
    s->powered = true;
    rig_reset_cause = RIG_RESET_SYSTEM; /* (the link has named it: its reset hook runs first) */
    rcc_settle(s);
}

static void rcc_init(Object *obj)
{
    RigStm32RccState *s = RIG_STM32_RCC(obj);
    memory_region_init_io(&s->iomem, obj, &rcc_ops, s, TYPE_RIG_STM32_RCC, 0x400);
    sysbus_init_mmio(SYS_BUS_DEVICE(obj), &s->iomem);
    s->hclk = qdev_init_clock_out(DEVICE(obj), "hclk");
    clock_set_hz(s->hclk, HSI_HZ);
    s->tim_clk[0] = qdev_init_clock_out(DEVICE(obj), "apb1-tim");
    s->tim_clk[1] = qdev_init_clock_out(DEVICE(obj), "apb2-tim");
    for (unsigned apb = 0; apb < 2; apb++) {
        s->tim_hz[apb] = HSI_HZ;
        clock_set_hz(s->tim_clk[apb], HSI_HZ);
    }
}

/* The register table of the chip the machine says ("chip": 405 or 411) */
static void rcc_realize(DeviceState *dev, Error **errp)
{
    RigStm32RccState *s = RIG_STM32_RCC(dev);
    switch (s->chip) {
    case 405:
        s->table = rcc_f405;
        s->count = ARRAY_SIZE(rcc_f405);
        break;
    case 411:
        s->table = rcc_f411;
        s->count = ARRAY_SIZE(rcc_f411);
        break;
    default:
        error_setg(errp, "rig-stm32f4-rcc: chip %u is not 405 or 411", s->chip);
        return;
    }
    assert(s->count <= RIG_RCC_REGISTERS);
}

static Property rcc_properties[] = {
    DEFINE_PROP_UINT32("hse-hz", RigStm32RccState, hse_hz, 8000000),
    DEFINE_PROP_UINT32("chip", RigStm32RccState, chip, 405),
    DEFINE_PROP_END_OF_LIST(),
};

static void rcc_class_init(ObjectClass *klass, void *data)
{
    DeviceClass *dc = DEVICE_CLASS(klass);
    dc->reset = rcc_reset;
    dc->realize = rcc_realize;
    device_class_set_props(dc, rcc_properties);
}

static const TypeInfo rcc_info = {
    .name = TYPE_RIG_STM32_RCC,
    .parent = TYPE_SYS_BUS_DEVICE,
    .instance_size = sizeof(RigStm32RccState),
    .instance_init = rcc_init,
    .class_init = rcc_class_init,
};

static void rcc_register_types(void) { type_register_static(&rcc_info); }

type_init(rcc_register_types)
