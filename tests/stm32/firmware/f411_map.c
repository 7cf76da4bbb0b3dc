/* The STM32F411 test firmware (run on rig-stm32f411 with a 25 MHz crystal): the F411's RCC at reset and
   its writable enable bits, its memory map (the last word of its 512 KB of flash and 128 KB of SRAM, and
   the word after each; the CCM RAM and the F405's peripherals it lacks: TIM6, TIM8, USART3, GPIOF, GPIOI,
   CAN1; and UART7, which QEMU's F405 SoC places and neither chip has),
   each probe's BusFault counted with BFAR, then 100 MHz from the 25 MHz HSE through the PLL as a Black
   Pill's SystemClock_Config does, the same loop timed with DWT_CYCCNT and SysTick at 16 and at 100 MHz.
   tests/stm32/test_f411.py judges the NAME=0xVALUE lines against RM0383. */
#include "semihost.h"
#include "spin_timing.h"
#include "stm32f405.h"

#define SHCSR REG(0xE000ED24u)
#define SHCSR_BUSFAULTENA (1u << 17)
#define CFSR REG(0xE000ED28u)
#define BFAR REG(0xE000ED38u)
#define CFSR_BUS_FAULTS 0x0000FF00u /* BFSR */
#define RCC_AHB1LPENR REG(RCC_BASE + 0x50u)
#define RCC_AHB2LPENR REG(RCC_BASE + 0x54u)
#define RCC_APB2LPENR REG(RCC_BASE + 0x64u)
#define RCC_PLLI2SCFGR REG(RCC_BASE + 0x84u)
#define RCC_DCKCFGR REG(RCC_BASE + 0x8Cu)
#define RCC_AHB3ENR REG(RCC_BASE + 0x38u)

static volatile uint32_t faults, fault_bfar, fault_bfsr;

void bus_fault_c(uint32_t *frame);
void bus_fault_c(uint32_t *frame)
{
    faults++;
    fault_bfsr = CFSR & CFSR_BUS_FAULTS;
    fault_bfar = BFAR;
    CFSR = CFSR_BUS_FAULTS; /* write 1 to clear */
    /* resume after the faulting load or store: a 32-bit Thumb instruction starts 0b11101, 0b11110 or
       0b11111 (ARMv7-M A5.1) */
    uint16_t first = *(const uint16_t *)frame[6];
    frame[6] += (first >> 11) >= 0x1Du ? 4u : 2u;
}

/* the exception frame (MSP or PSP, as EXC_RETURN says) to bus_fault_c */
__attribute__((naked)) void bus_fault_handler(void);
void bus_fault_handler(void)
{
    __asm volatile("tst lr, #4\n"
                   "ite eq\n"
                   "mrseq r0, msp\n"
                   "mrsne r0, psp\n"
                   "b bus_fault_c\n");
}

/* Reads @address: NAME_faults (0 or 1), and NAME_bfar with the fault's BFSR when it faulted */
static void probe(const char *faults_name, const char *bfar_name, uint32_t address)
{
    uint32_t before = faults;
    (void)REG(address);
    report(faults_name, faults - before);
    if (faults != before) {
        report(bfar_name, fault_bfar);
    }
}

#define PROBE(name, address) probe(name "_faults", name "_bfar", address)

static void rcc(void)
{
    report("rcc_cr_reset", RCC_CR);
    report("rcc_pllcfgr_reset", RCC_PLLCFGR);
    report("rcc_ahb1enr_reset", RCC_AHB1ENR);
    report("rcc_ahb1lpenr_reset", RCC_AHB1LPENR);
    report("rcc_ahb2lpenr_reset", RCC_AHB2LPENR);
    report("rcc_apb1lpenr_reset", RCC_APB1LPENR);
    report("rcc_apb2lpenr_reset", RCC_APB2LPENR);
    report("rcc_plli2scfgr_reset", RCC_PLLI2SCFGR);
    report("rcc_dckcfgr_reset", RCC_DCKCFGR);
    RCC_AHB3ENR = 0xFFFFFFFFu; /* reserved on the F411 (no FSMC) */
    report("rcc_ahb3enr_ones", RCC_AHB3ENR);
    RCC_AHB1ENR = 0xFFFFFFFFu;
    report("rcc_ahb1enr_ones", RCC_AHB1ENR);
    RCC_APB1ENR = 0xFFFFFFFFu;
    report("rcc_apb1enr_ones", RCC_APB1ENR);
    RCC_APB2ENR = 0xFFFFFFFFu;
    report("rcc_apb2enr_ones", RCC_APB2ENR);
    RCC_DCKCFGR = 0xFFFFFFFFu;
    report("rcc_dckcfgr_ones", RCC_DCKCFGR);
    RCC_DCKCFGR = 0;
}

static void memory_map(void)
{
    SHCSR |= SHCSR_BUSFAULTENA;
    PROBE("flash_last", 0x0807FFFCu);
    PROBE("flash_end", 0x08080000u);
    PROBE("alias_end", 0x00080000u);
    PROBE("sram_last", 0x2001FFFCu);
    PROBE("sram_end", 0x20020000u);
    PROBE("ccm", 0x10000000u);
    PROBE("tim3", TIM3_BASE);
    PROBE("tim11", TIM11_BASE);
    PROBE("gpioh", GPIO_BASE(7u));
    PROBE("tim6", TIM6_BASE);
    PROBE("tim8", TIM8_BASE);
    PROBE("usart3", USART3_BASE);
    PROBE("gpiof", GPIO_BASE(5u));
    PROBE("gpioi", GPIO_BASE(8u));
    PROBE("can1", 0x40006400u);
    PROBE("uart7", 0x40007800u);
    report("bus_fault_bfsr", fault_bfsr);
    uint32_t before = faults;
    REG(TIM6_BASE) = 1u; /* a store there: a bus error too */
    report("tim6_store_faults", faults - before);
}

/* 100 MHz from the 25 MHz HSE: PLLM 25, PLLN 200, PLLP 2 (RM0383 6.3.2), APB1 /2, three wait states */
static void clock_to_100mhz(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_PWREN;
    PWR_CR |= 3u << 14;
    RCC_CR |= RCC_CR_HSEON;
    while (!(RCC_CR & RCC_CR_HSERDY)) {
    }
    RCC_CFGR |= RCC_CFGR_PPRE1_DIV2;
    RCC_PLLCFGR = 25u | (200u << 6) | RCC_PLLCFGR_PLLSRC_HSE | (4u << 24);
    RCC_CR |= RCC_CR_PLLON;
    while (!(RCC_CR & RCC_CR_PLLRDY)) {
    }
    FLASH_ACR = FLASH_ACR_ICEN | FLASH_ACR_DCEN | FLASH_ACR_PRFTEN | 3u;
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC_CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL) {
    }
    report("rcc_pllcfgr", RCC_PLLCFGR);
    report("rcc_cfgr_pll", RCC_CFGR);
}

int main(void)
{
    rcc();
    RCC_AHB1ENR = 0;
    RCC_APB1ENR = 0;
    RCC_APB2ENR = 0;
    RCC_AHB1ENR = 0x9Fu;    /* GPIOA..E, H */
    RCC_APB1ENR = 1u << 1;  /* TIM3 */
    RCC_APB2ENR = 1u << 18; /* TIM11 */
    memory_map();
    DEMCR |= DEMCR_TRCENA;
    DWT_CTRL |= 1u;
    time_spin("spin_cycles_16mhz", "spin_ticks_16mhz");
    clock_to_100mhz();
    time_spin("spin_cycles_100mhz", "spin_ticks_100mhz");
    return 0;
}
