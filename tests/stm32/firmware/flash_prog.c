/* The flash programming test firmware of the STM32 tier (RM0090 3.5-3.9): writes to a locked flash and
   without CR.PG, the unlock, sector erases (16, 64 and 128 KB sectors) timed from STRT to EOP with
   DWT_CYCCNT at the 16 MHz HSI, a word programmed and timed, the 1->0 rule, a write of the wrong size for
   PSIZE, a misaligned one (bytes on the bus), byte and half-word programming, the alias at 0, the FLASH interrupt's count;
   then settings written into its .fc_config section (sector 1), a wrong key, and a system reset (AIRCR.SYSRESETREQ). Its second
   boot (RCC_CSR's reset flags tell it) reports the reset flags, the CR lock and the settings read back. */
#include "semihost.h"
#include "stm32f405.h"

#define FLASH_BASE 0x08000000u
#define SECTOR1 (FLASH_BASE + 0x4000u)   /* 16 KB */
#define SECTOR4 (FLASH_BASE + 0x10000u)  /* 64 KB */
#define SECTOR11 (FLASH_BASE + 0xE0000u) /* 128 KB */
#define WORD(addr) (*(volatile uint32_t *)(addr))
#define HALF(addr) (*(volatile uint16_t *)(addr))
#define BYTE(addr) (*(volatile uint8_t *)(addr))
#define PSIZE_X8 0u
#define PSIZE_X16 1u
#define PSIZE_X32 2u
#define RCC_CSR_FLAGS 0xFE000000u
#define SETTINGS_WORDS 4u

static volatile uint32_t eop_interrupts;
static const uint32_t settings[SETTINGS_WORDS] = { 0x52494731u, 0x000001F4u, 0x3F800000u, 0xC0FFEE00u };
/* the settings' place: the section the rig reads a firmware's settings from (rig/mcu/stm32_image.py),
   sector 1 (16 KB) to itself */
__attribute__((section(".fc_config"), aligned(0x4000), used)) static const uint8_t fc_config[0x4000];
#define SETTINGS_SECTOR 1u
#define SETTINGS ((uint32_t)(uintptr_t)fc_config)

void flash_handler(void);
void flash_handler(void)
{
    eop_interrupts++;
    FLASH_SR = FLASH_SR_EOP; /* write 1 to clear */
}

/* The core asleep until the operation's end (EOP, with EOPIE): the cycles from @start */
static uint32_t wait_eop(uint32_t start)
{
    __asm volatile("cpsid i");
    while (!(FLASH_SR & FLASH_SR_EOP)) {
        __asm volatile("wfi");
    }
    uint32_t cycles = DWT_CYCCNT - start;
    __asm volatile("cpsie i"); /* the handler runs */
    return cycles;
}

static uint32_t erase(unsigned sector)
{
    FLASH_CR = FLASH_CR_SER | FLASH_CR_SNB(sector) | FLASH_CR_PSIZE(PSIZE_X32) | FLASH_CR_EOPIE;
    uint32_t start = DWT_CYCCNT;
    FLASH_CR |= FLASH_CR_STRT;
    return wait_eop(start);
}

static void program_word(uint32_t addr, uint32_t value)
{
    FLASH_CR = FLASH_CR_PG | FLASH_CR_PSIZE(PSIZE_X32) | FLASH_CR_EOPIE;
    WORD(addr) = value;
    while (FLASH_SR & FLASH_SR_BSY) {
    }
}

static void first_boot(void)
{
    RCC_CSR |= RCC_CSR_RMVF; /* the power-on flags cleared: the next boot sees only its reset's */
    DWT_CTRL |= 1u;          /* CYCCNTENA */
    NVIC_ISER(0) = 1u << FLASH_IRQ;
    report("flash_sr_reset", FLASH_SR);
    report("flash_cr_reset", FLASH_CR);
    uint32_t before = WORD(SECTOR11);
    WORD(SECTOR11) = 0;
    report("locked_write_sr", FLASH_SR);
    report("locked_write_word", WORD(SECTOR11));
    report("locked_write_before", before);
    FLASH_SR = FLASH_SR_PGSERR;
    report("sr_cleared", FLASH_SR);

    FLASH_KEYR = FLASH_KEY1;
    FLASH_KEYR = FLASH_KEY2;
    report("cr_unlocked", FLASH_CR);
    FLASH_CR = FLASH_CR_PSIZE(PSIZE_X32);
    WORD(SECTOR11) = 0;
    report("no_pg_sr", FLASH_SR);
    report("no_pg_word", WORD(SECTOR11));
    FLASH_SR = FLASH_SR_PGSERR;

    /* a word programmed: BSY at once, then its time */
    FLASH_CR = FLASH_CR_PG | FLASH_CR_PSIZE(PSIZE_X32) | FLASH_CR_EOPIE;
    uint32_t start = DWT_CYCCNT;
    WORD(SECTOR11) = 0x12345678u;
    report("program_sr_busy", FLASH_SR);
    report("program_cycles", wait_eop(start));
    report("program_word", WORD(SECTOR11));
    report("program_alias", WORD(SECTOR11 - FLASH_BASE));
    program_word(SECTOR11, 0xF0F0F0F0u);
    report("and_word", WORD(SECTOR11));

    /* the wrong size for PSIZE, a misaligned word, then bytes and half-words with their PSIZE */
    BYTE(SECTOR11 + 4u) = 0x5Au;
    report("psize_sr", FLASH_SR);
    report("psize_word", WORD(SECTOR11 + 4u));
    FLASH_SR = FLASH_SR_PGPERR;
    WORD(SECTOR11 + 10u) = 0;
    report("misaligned_sr", FLASH_SR);
    report("misaligned_word", WORD(SECTOR11 + 8u));
    FLASH_SR = FLASH_SR_PGPERR;
    FLASH_CR = FLASH_CR_PG | FLASH_CR_PSIZE(PSIZE_X8) | FLASH_CR_EOPIE;
    BYTE(SECTOR11 + 4u) = 0x5Au;
    while (FLASH_SR & FLASH_SR_BSY) {
    }
    FLASH_CR = FLASH_CR_PG | FLASH_CR_PSIZE(PSIZE_X16) | FLASH_CR_EOPIE;
    HALF(SECTOR11 + 6u) = 0x1234u;
    while (FLASH_SR & FLASH_SR_BSY) {
    }
    report("x8_x16_word", WORD(SECTOR11 + 4u));
    report("sr_after_programs", FLASH_SR & ~FLASH_SR_EOP);

    /* sector erases, each timed to its EOP */
    report("erase11_cycles", erase(11));
    report("erase11_first", WORD(SECTOR11));
    report("erase11_word1", WORD(SECTOR11 + 4u));
    report("erase11_last", WORD(SECTOR11 + 0x1FFFCu));
    report("erase1_cycles", erase(1));
    report("erase4_cycles", erase(4));
    report("cr_after_erase", FLASH_CR);
    report("eop_interrupts", eop_interrupts);

    /* the settings, into their sector, erased first */
    report("settings_at", SETTINGS);
    erase(SETTINGS_SECTOR);
    for (unsigned i = 0; i < SETTINGS_WORDS; i++) {
        program_word(SETTINGS + 4u * i, settings[i]);
    }
    FLASH_CR = FLASH_CR_LOCK;
    report("cr_relocked", FLASH_CR);
    FLASH_KEYR = 0x12345678u; /* a wrong key: locked until the next reset */
    FLASH_KEYR = FLASH_KEY1;
    FLASH_KEYR = FLASH_KEY2;
    report("cr_wrong_key", FLASH_CR);
    put_text("resetting\n");
    SCB_AIRCR = SCB_AIRCR_SYSRESETREQ;
    for (;;) {
    }
}

int main(void)
{
    uint32_t flags = RCC_CSR & RCC_CSR_FLAGS;
    if (flags == 0x0E000000u) { /* PORRSTF, PINRSTF, BORRSTF: power-on */
        first_boot();
    }
    report("boot2_csr", flags);
    report("boot2_cr", FLASH_CR);
    for (unsigned i = 0; i < SETTINGS_WORDS; i++) {
        char name[] = "settings_0";
        name[9] = (char)('0' + i);
        report(name, WORD(SETTINGS + 4u * i));
    }
    FLASH_KEYR = FLASH_KEY1;
    FLASH_KEYR = FLASH_KEY2;
    report("boot2_cr_unlocked", FLASH_CR);
    for (uint32_t i = 0; i < 200000u; i++) { /* a few ms, so a linked session sees it running before the exit */
        __asm volatile("nop");
    }
    put_text("done\n");
    return 0;
}
