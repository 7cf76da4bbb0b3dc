/* External interrupts from pins (RM0090 9.2: SYSCFG_EXTICR1..4; 12.3: EXTI), run with
   -M rig-stm32f405,wires=PD1-PA0 (tests/stm32/test_exti.py):
   * SYSCFG's and EXTI's registers at reset, with all ones written, and SYSCFG with its clock off;
   * line 0 on PA0, driven from outside by PD1 (an output of the firmware's): PR set by the selected
     edge whether IMR masks it or not, cleared by writing 1; unmasked, an interrupt on EXTI0 (NVIC 6)
     for each selected edge only (rising, then both);
   * line 5 on PB5 and line 13 on PC13, outputs the firmware toggles (the input stays on in output mode,
     RM0090 8.3.10): EXTI9_5 (NVIC 23) and EXTI15_10 (NVIC 40); PA5's edges do not reach line 5 while
     EXTICR2 selects port B;
   * SWIER: line 1 raised by software (EXTI1, NVIC 7), SWIER cleared with PR;
   * a handler that leaves PR set is entered again (line 2 by SWIER: the third entry clears it).
   Values go out as NAME=0xVALUE lines through semihosting. */
#include "semihost.h"
#include "stm32f405.h"

#define SYSCFG 0x40013800u
#define SYSCFG_REG(off) REG(SYSCFG + (off))
#define EXTICR(n) SYSCFG_REG(0x08u + 4u * ((n)-1u)) /* n 1..4 */
#define EXTI 0x40013C00u
#define EXTI_IMR REG(EXTI + 0x00u)
#define EXTI_EMR REG(EXTI + 0x04u)
#define EXTI_RTSR REG(EXTI + 0x08u)
#define EXTI_FTSR REG(EXTI + 0x0Cu)
#define EXTI_SWIER REG(EXTI + 0x10u)
#define EXTI_PR REG(EXTI + 0x14u)
#define APB2ENR_SYSCFGEN (1u << 14)
#define MODE_OUTPUT 1u

static volatile uint32_t entries[16], pr_seen[16];

static void count(unsigned line)
{
    pr_seen[line] = EXTI_PR;
    entries[line]++;
    EXTI_PR = 1u << line;
}

void exti0_handler(void) { count(0); }
void exti1_handler(void) { count(1); }
void exti9_5_handler(void) { count(5); }
void exti15_10_handler(void) { count(13); }

/* leaves PR set twice: the NVIC input stays high and the handler runs again */
void exti2_handler(void)
{
    if (++entries[2] == 3u) {
        EXTI_PR = 1u << 2;
    }
}

static void output(uint32_t port, unsigned pin)
{
    RCC_AHB1ENR |= 1u << port;
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2 * pin))) | (MODE_OUTPUT << (2 * pin));
}

static void set_pin(uint32_t port, unsigned pin, unsigned level)
{
    GPIO_BSRR(port) = level ? 1u << pin : 1u << (16 + pin);
    __asm volatile("dsb; isb"); /* (the interrupt, if any, is taken before the next report) */
}

static void registers(void)
{
    EXTICR(1) = 0x1111u; /* clock off: lost */
    RCC_APB2ENR |= APB2ENR_SYSCFGEN;
    report("syscfg_exticr1_clock_off", EXTICR(1));
    static const char *const syscfg_names[] = { "syscfg_memrmp",  "syscfg_pmc",     "syscfg_exticr1",
                                                "syscfg_exticr2", "syscfg_exticr3", "syscfg_exticr4" };
    for (unsigned i = 0; i < 6; i++) {
        report(syscfg_names[i], SYSCFG_REG(4u * i));
    }
    report("syscfg_cmpcr", SYSCFG_REG(0x20u));
    static const char *const exti_names[] = {
        "exti_imr", "exti_emr", "exti_rtsr", "exti_ftsr", "exti_swier", "exti_pr"
    };
    for (unsigned i = 0; i < 6; i++) {
        report(exti_names[i], REG(EXTI + 4u * i));
    }
    SYSCFG_REG(0x04u) = 0xFFFFFFFFu;
    report("syscfg_pmc_ones", SYSCFG_REG(0x04u));
    SYSCFG_REG(0x04u) = 0;
    EXTICR(4) = 0xFFFFFFFFu;
    report("syscfg_exticr4_ones", EXTICR(4));
    EXTICR(4) = 0;
    SYSCFG_REG(0x20u) = 1u;
    report("syscfg_cmpcr_powered", SYSCFG_REG(0x20u));
    SYSCFG_REG(0x20u) = 0;
    for (unsigned i = 0; i < 4; i++) { /* IMR, EMR, RTSR, FTSR */
        REG(EXTI + 4u * i) = 0xFFFFFFFFu;
        char name[] = "exti_ones_0";
        name[10] = (char)('0' + i);
        report(name, REG(EXTI + 4u * i));
        REG(EXTI + 4u * i) = 0;
    }
}

/* line 0 from PA0, which PD1 drives through the wire */
static void line0(void)
{
    output(PORT_D, 1);
    RCC_AHB1ENR |= 1u << PORT_A; /* PA0 an input (reset) */
    EXTI_RTSR = 1u;
    set_pin(PORT_D, 1, 1);
    report("line0_masked_pr", EXTI_PR);
    report("line0_masked_entries", entries[0]);
    EXTI_PR = 1u;
    report("line0_pr_cleared", EXTI_PR);
    set_pin(PORT_D, 1, 0);
    report("line0_falling_unselected_pr", EXTI_PR);
    EXTI_IMR = 1u;
    NVIC_ISER(0) = 1u << 6;
    set_pin(PORT_D, 1, 1);
    report("line0_rising_entries", entries[0]);
    report("line0_rising_pr_in_handler", pr_seen[0]);
    set_pin(PORT_D, 1, 0);
    report("line0_falling_entries", entries[0]);
    EXTI_FTSR = 1u;
    set_pin(PORT_D, 1, 1);
    set_pin(PORT_D, 1, 0);
    report("line0_both_entries", entries[0]);
    report("line0_pr_after", EXTI_PR);
}

/* line 5 on port B, line 13 on port C, from the firmware's own outputs */
static void lines_b_c(void)
{
    output(PORT_B, 5);
    output(PORT_A, 5);
    output(PORT_C, 13);
    EXTICR(2) = 1u << 4; /* EXTI5: PB5 */
    EXTICR(4) = 2u << 4; /* EXTI13: PC13 */
    EXTI_RTSR = EXTI_FTSR = (1u << 5) | (1u << 13);
    EXTI_IMR = (1u << 5) | (1u << 13);
    NVIC_ISER(0) = 1u << 23;
    NVIC_ISER(1) = 1u << (40 - 32);
    set_pin(PORT_A, 5, 1);
    set_pin(PORT_A, 5, 0);
    report("line5_pa5_entries", entries[5]);
    set_pin(PORT_B, 5, 1);
    report("line5_pb5_rising_entries", entries[5]);
    report("line5_pr_in_handler", pr_seen[5]);
    set_pin(PORT_B, 5, 0);
    report("line5_pb5_falling_entries", entries[5]);
    set_pin(PORT_C, 13, 1);
    set_pin(PORT_C, 13, 0);
    report("line13_pc13_entries", entries[13]);
    report("line13_pr_in_handler", pr_seen[13]);
}

static void software(void)
{
    EXTI_IMR |= (1u << 1) | (1u << 2);
    NVIC_ISER(0) = (1u << 7) | (1u << 8);
    EXTI_SWIER = 1u << 1;
    __asm volatile("dsb; isb");
    report("swier1_entries", entries[1]);
    report("swier1_pr_in_handler", pr_seen[1]);
    report("swier_after_pr_write", EXTI_SWIER);
    EXTI_SWIER = 1u << 2;
    __asm volatile("dsb; isb");
    report("swier2_entries", entries[2]);
    report("pr_end", EXTI_PR);
}

int main(void)
{
    registers();
    line0();
    lines_b_c();
    software();
    return 0;
}
