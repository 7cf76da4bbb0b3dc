/* The F411's own register tables (run on rig-stm32f411, and on rig-stm32f405 for the F405's), at the 16 MHz
   HSI: PWR, the FLASH interface and ports A, B, C and H at reset; PWR_CR and FLASH_ACR with all ones
   written; CSR.VOSRDY after each VOS; sector erases timed from STRT to EOP with DWT_CYCCNT (sector 5, 128
   KB, at x32; sector 2, 16 KB, at x16; sector 4, 64 KB, at x8), each with a word programmed in it before
   and one in the next sector that must stay; an erase of sector 8 (none on the F411); TIM2's period with
   APB1 divided by 1, 4 and 8, with and without RCC_DCKCFGR.TIMPRE (which only the F411 has); and last a
   mass erase at x32, timed from RAM.
   tests/stm32/test_f411_regs.py judges the NAME=0xVALUE lines against RM0383, RM0090 and DS10314. */
#include "semihost.h"
#include "stm32f405.h"

#define PWR_CSR REG(0x40007004u)
#define FLASH_OPTCR REG(0x40023C14u)
#define RCC_DCKCFGR REG(RCC_BASE + 0x8Cu)
#define DCKCFGR_TIMPRE (1u << 24)
#define RCC_APB1ENR_TIM2EN (1u << 0)
#define PORT_H 7u
#define FLASH_BASE 0x08000000u
#define PSIZE_X8 0u
#define PSIZE_X16 1u
#define PSIZE_X32 2u
#define WORD(addr) (*(volatile uint32_t *)(addr))
#define TIM2_ARR 999u
#define TIM2_PERIODS 10u

/* The main flash's sector @n: 4 x 16 KB, one of 64 KB, then 128 KB each (RM0383 table 4, RM0090 table 5) */
static uint32_t sector_address(unsigned n)
{
    return FLASH_BASE + (n < 4u ? n * 0x4000u : n == 4u ? 0x10000u : (n - 4u) * 0x20000u);
}

void flash_handler(void);
void flash_handler(void) { FLASH_SR = FLASH_SR_EOP; }

/* The core asleep until EOP (with EOPIE): the cycles from @start */
static uint32_t wait_eop(uint32_t start)
{
    __asm volatile("cpsid i");
    while (!(FLASH_SR & FLASH_SR_EOP)) {
        __asm volatile("wfi");
    }
    uint32_t cycles = DWT_CYCCNT - start;
    __asm volatile("cpsie i");
    return cycles;
}

static void program_word(uint32_t addr, uint32_t value)
{
    FLASH_CR = FLASH_CR_PG | FLASH_CR_PSIZE(PSIZE_X32) | FLASH_CR_EOPIE;
    WORD(addr) = value;
    wait_eop(DWT_CYCCNT);
}

/* Sector @n erased with @psize: NAME_cycles, NAME_word (a word programmed in it before) and NAME_next (one
   programmed in the next sector, which stays) */
static void erase(const char *cycles_name, const char *word_name, const char *next_name, unsigned n, unsigned psize)
{
    program_word(sector_address(n) + 0x100u, 0x12345678u);
    program_word(sector_address(n + 1u), 0x9ABCDEF0u);
    FLASH_CR = FLASH_CR_SER | FLASH_CR_SNB(n) | FLASH_CR_PSIZE(psize) | FLASH_CR_EOPIE;
    uint32_t start = DWT_CYCCNT;
    FLASH_CR |= FLASH_CR_STRT;
    report(cycles_name, wait_eop(start));
    report(word_name, WORD(sector_address(n) + 0x100u));
    report(next_name, WORD(sector_address(n + 1u)));
}

static void at_reset(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_PWREN;
    report("pwr_cr_reset", PWR_CR);
    report("pwr_csr_reset", PWR_CSR);
    report("flash_acr_reset", FLASH_ACR);
    report("flash_sr_reset", FLASH_SR);
    report("flash_cr_reset", FLASH_CR);
    report("flash_optcr_reset", FLASH_OPTCR);
    RCC_AHB1ENR |= 0x87u; /* GPIOA, B, C, H */
    report("gpioa_moder_reset", GPIO_MODER(PORT_A));
    report("gpioa_ospeedr_reset", GPIO_OSPEEDR(PORT_A));
    report("gpioa_pupdr_reset", GPIO_PUPDR(PORT_A));
    report("gpiob_moder_reset", GPIO_MODER(PORT_B));
    report("gpiob_ospeedr_reset", GPIO_OSPEEDR(PORT_B));
    report("gpiob_pupdr_reset", GPIO_PUPDR(PORT_B));
    report("gpioc_moder_reset", GPIO_MODER(PORT_C));
    report("gpioc_ospeedr_reset", GPIO_OSPEEDR(PORT_C));
    report("gpioh_moder_reset", GPIO_MODER(PORT_H));
}

static void writable(void)
{
    uint32_t cr = PWR_CR;
    PWR_CR = 0xFFFFFFFFu;
    report("pwr_cr_ones", PWR_CR);
    PWR_CR = cr;
    PWR_CSR = 0xFFFFFFFFu;
    report("pwr_csr_ones", PWR_CSR);
    PWR_CSR = 0;
    FLASH_ACR = 0xFFFFFFFFu;
    report("flash_acr_ones", FLASH_ACR);
    FLASH_ACR = 0;
    /* each scale the regulator can be asked for (the F411's VOS[15:14]: 01 scale 3, 10 scale 2, 11 scale 1) */
    static const char *const names[3][2] = { { "vos1_cr", "vos1_csr" },
                                             { "vos2_cr", "vos2_csr" },
                                             { "vos3_cr", "vos3_csr" } };
    for (uint32_t vos = 1u; vos <= 3u; vos++) {
        PWR_CR = (PWR_CR & ~(3u << 14)) | vos << 14;
        report(names[vos - 1u][0], PWR_CR);
        report(names[vos - 1u][1], PWR_CSR);
    }
    PWR_CR = cr;
}

static void flash(void)
{
    NVIC_ISER(0) = 1u << FLASH_IRQ;
    FLASH_KEYR = FLASH_KEY1;
    FLASH_KEYR = FLASH_KEY2;
    erase("erase5_x32_cycles", "erase5_word", "erase5_next", 5u, PSIZE_X32);
    erase("erase2_x16_cycles", "erase2_word", "erase2_next", 2u, PSIZE_X16);
    erase("erase4_x8_cycles", "erase4_word", "erase4_next", 4u, PSIZE_X8);
    /* sector 8: the F411 has 0-7 */
    program_word(sector_address(7u), 0x0F1E2D3Cu);
    FLASH_CR = FLASH_CR_SER | FLASH_CR_SNB(8u) | FLASH_CR_PSIZE(PSIZE_X32) | FLASH_CR_EOPIE;
    FLASH_CR |= FLASH_CR_STRT;
    report("snb8_sr", FLASH_SR);
    report("snb8_cr", FLASH_CR);
    if (FLASH_SR & FLASH_SR_BSY) { /* a sector there (the F405's 1 MB): its erase ends */
        wait_eop(DWT_CYCCNT);
    }
    report("snb8_sector7", WORD(sector_address(7u)));
    FLASH_CR = FLASH_CR_LOCK;
}

/* TIM2 counting TIM2_PERIODS periods of TIM2_ARR + 1 ticks (PSC 0), in HCLK cycles: UIF to UIF */
static uint32_t tim2_periods(void)
{
    TIM_PSC(TIM2_BASE) = 0;
    TIM_ARR(TIM2_BASE) = TIM2_ARR;
    TIM_EGR(TIM2_BASE) = TIM_EGR_UG;
    TIM_SR(TIM2_BASE) = 0;
    TIM_CR1(TIM2_BASE) = TIM_CR1_CEN;
    while (!(TIM_SR(TIM2_BASE) & TIM_SR_UIF)) {
    }
    uint32_t start = DWT_CYCCNT;
    for (unsigned i = 0; i < TIM2_PERIODS; i++) {
        TIM_SR(TIM2_BASE) = 0;
        while (!(TIM_SR(TIM2_BASE) & TIM_SR_UIF)) {
        }
    }
    uint32_t cycles = DWT_CYCCNT - start;
    TIM_CR1(TIM2_BASE) = 0;
    return cycles;
}

/* A mass erase (MER) at x32, timed from STRT to EOP, reported, then the end of the run: it erases the code,
   this firmware's included, so what runs after it is here, in RAM (.ramfunc, copied with .data by
   startup.c), and calls nothing in flash; interrupts stay masked (the vectors are erased too: the FLASH
   interrupt only pends and wakes WFI). The line's text and its digits are in RAM as well. */
#define MASS_ERASE_NAME "mass_erase_x32_cycles=0x"
__attribute__((section(".ramfunc"), noinline, long_call)) static void mass_erase_and_exit(void)
{
    static char line[] = MASS_ERASE_NAME "00000000\ndone\n";
    static uint32_t exit_block[2] = { ADP_STOPPED_APPLICATION_EXIT, 0 };
    __asm volatile("cpsid i");
    FLASH_CR = FLASH_CR_MER | FLASH_CR_PSIZE(PSIZE_X32) | FLASH_CR_EOPIE;
    uint32_t start = DWT_CYCCNT;
    FLASH_CR |= FLASH_CR_STRT;
    while (!(FLASH_SR & FLASH_SR_EOP)) {
        __asm volatile("wfi");
    }
    uint32_t cycles = DWT_CYCCNT - start;
    for (unsigned i = 0; i < 8u; i++) {
        uint32_t digit = cycles >> (28u - 4u * i) & 0xFu;
        line[sizeof MASS_ERASE_NAME - 1u + i] = (char)(digit < 10u ? '0' + digit : 'a' + digit - 10u);
    }
    register uint32_t r0 __asm("r0") = SYS_WRITE0;
    register const void *r1 __asm("r1") = line;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    r0 = SYS_EXIT_EXTENDED;
    r1 = exit_block;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    for (;;) {
    }
}

static void timpre(void)
{
    static const struct {
        uint32_t ppre1, timpre;
        const char *name;
    } cases[] = {
        { 0u, 0u, "tim2_div1_cycles" },
        { 0u, DCKCFGR_TIMPRE, "tim2_div1_timpre_cycles" },
        { RCC_CFGR_PPRE1_DIV4, 0u, "tim2_div4_cycles" },
        { RCC_CFGR_PPRE1_DIV4, DCKCFGR_TIMPRE, "tim2_div4_timpre_cycles" },
        { RCC_CFGR_PPRE1_DIV8, 0u, "tim2_div8_cycles" },
        { RCC_CFGR_PPRE1_DIV8, DCKCFGR_TIMPRE, "tim2_div8_timpre_cycles" },
    };
    RCC_APB1ENR |= RCC_APB1ENR_TIM2EN;
    for (unsigned i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_PPRE1) | cases[i].ppre1;
        RCC_DCKCFGR = cases[i].timpre;
        report(cases[i].name, tim2_periods());
    }
    RCC_DCKCFGR = 0xFFFFFFFFu;
    report("rcc_dckcfgr_ones", RCC_DCKCFGR);
    RCC_DCKCFGR = 0;
    RCC_CFGR &= ~RCC_CFGR_PPRE1;
}

int main(void)
{
    DEMCR |= DEMCR_TRCENA;
    DWT_CTRL |= 1u;
    at_reset();
    writable();
    flash();
    timpre();
    FLASH_KEYR = FLASH_KEY1;
    FLASH_KEYR = FLASH_KEY2;
    mass_erase_and_exit();
    return 1; /* (not reached) */
}
