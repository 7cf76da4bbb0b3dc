/* The STM32G431's registers the bridge firmware uses, and nothing else: our own minimal definitions
   (no vendor SDK is reachable from the project's machines). Addresses and bit positions are facts from
   the reference manual RM0440 (Rev 4 where a section number is given; the register map tables at the
   end of each chapter) and the STM32G431 datasheet (DS12589: alternate functions, memory sizes). Where a
   section number is not given the chapter is named: check it there before relying on it on a bench
   (docs/bridge-firmware.md lists what has not been verified on hardware). */
#ifndef STM32G4_REGS_H
#define STM32G4_REGS_H

#include <stdint.h>

#define REG(addr) (*(volatile uint32_t *)(uintptr_t)(addr))
#define BIT(n) (1u << (n))

/* ---- memory map (RM0440 §2.2.2, DS12589 §3.4): 128 KB flash; SRAM1 16 KB at 0x20000000, SRAM2 6 KB
   at 0x20004000 and the 10 KB CCM SRAM aliased at 0x20005800: 32 KB contiguous */
#define FLASH_BASE 0x08000000u
#define FLASH_SIZE (128u * 1024u)
#define SRAM_BASE 0x20000000u
#define SRAM_SIZE (32u * 1024u)

/* ---- Cortex-M4 system control (ARMv7-M ARM B3.2; PM0214) */
#define SCB_VTOR REG(0xE000ED08u)
#define SCB_AIRCR REG(0xE000ED0Cu)
#define SCB_CPACR REG(0xE000ED88u)
#define NVIC_ISER(n) REG(0xE000E100u + 4u * (n))
#define NVIC_IPR8(irq) (*(volatile uint8_t *)(uintptr_t)(0xE000E400u + (irq)))
#define AIRCR_VECTKEY (0x05FAu << 16)
#define AIRCR_SYSRESETREQ BIT(2)

/* ---- FLASH interface (RM0440 §5.7.1 FLASH_ACR; wait states: §5.3.3 Table 29, 4 WS up to 170 MHz in
   range 1 boost) */
#define FLASH_ACR REG(0x40022000u)
#define FLASH_ACR_LATENCY_MASK 0xFu
#define FLASH_ACR_PRFTEN BIT(8)
#define FLASH_ACR_ICEN BIT(9)
#define FLASH_ACR_DCEN BIT(10)

/* ---- PWR (RM0440 §6.4): range 1 and its boost mode (R1MODE = 0) for 150..170 MHz (§6.1.5) */
#define PWR_BASE 0x40007000u
#define PWR_CR1 REG(PWR_BASE + 0x00u)
#define PWR_CR1_VOS_MASK (3u << 9)
#define PWR_CR1_VOS_RANGE1 (1u << 9)
#define PWR_SR2 REG(PWR_BASE + 0x14u)
#define PWR_SR2_VOSF BIT(10)
#define PWR_CR5 REG(PWR_BASE + 0x80u)
#define PWR_CR5_R1MODE BIT(8)

/* ---- RCC (RM0440 §7.4) */
#define RCC_BASE 0x40021000u
#define RCC_CR REG(RCC_BASE + 0x00u)
#define RCC_CR_HSION BIT(8)
#define RCC_CR_HSIRDY BIT(10)
#define RCC_CR_PLLON BIT(24)
#define RCC_CR_PLLRDY BIT(25)
#define RCC_CFGR REG(RCC_BASE + 0x08u)
#define RCC_CFGR_SW_MASK 3u
#define RCC_CFGR_SW_PLL 3u
#define RCC_CFGR_SWS_MASK (3u << 2)
#define RCC_CFGR_SWS_PLL (3u << 2)
#define RCC_CFGR_HPRE_MASK (0xFu << 4)
#define RCC_CFGR_HPRE_DIV2 (8u << 4)
#define RCC_PLLCFGR REG(RCC_BASE + 0x0Cu)
#define RCC_PLLCFGR_SRC_HSI16 2u
#define RCC_PLLCFGR_M(m) (((m)-1u) << 4) /* input divider 1..16 */
#define RCC_PLLCFGR_N(n) ((n) << 8)      /* VCO multiplier 8..127 */
#define RCC_PLLCFGR_REN BIT(24)          /* the R output: SYSCLK */
#define RCC_PLLCFGR_R_DIV2 (0u << 25)
#define RCC_AHB1ENR REG(RCC_BASE + 0x48u)
#define RCC_AHB1ENR_DMA1EN BIT(0)
#define RCC_AHB1ENR_DMAMUX1EN BIT(2)
#define RCC_AHB2ENR REG(RCC_BASE + 0x4Cu)
#define RCC_AHB2ENR_GPIOAEN BIT(0)
#define RCC_AHB2ENR_GPIOBEN BIT(1)
#define RCC_APB1ENR1 REG(RCC_BASE + 0x58u)
#define RCC_APB1ENR1_TIM2EN BIT(0)
#define RCC_APB1ENR1_USART2EN BIT(17)
#define RCC_APB1ENR1_I2C1EN BIT(21)
#define RCC_APB1ENR1_FDCANEN BIT(25)
#define RCC_APB1ENR1_PWREN BIT(28)
#define RCC_APB1ENR1_I2C3EN BIT(30)
#define RCC_APB2ENR REG(RCC_BASE + 0x60u)
#define RCC_APB2ENR_SYSCFGEN BIT(0)
#define RCC_APB2ENR_USART1EN BIT(14)
#define RCC_CCIPR REG(RCC_BASE + 0x88u)
#define RCC_CCIPR_FDCANSEL_PCLK1 (2u << 24)
#define RCC_CCIPR_FDCANSEL_MASK (3u << 24)
#define RCC_CSR REG(RCC_BASE + 0x94u)
#define RCC_CSR_LSION BIT(0)
#define RCC_CSR_LSIRDY BIT(1)
#define RCC_CSR_RMVF BIT(23)
#define RCC_CSR_IWDGRSTF BIT(29)

/* ---- SYSCFG (RM0440 §10 "System configuration controller", SYSCFG_CFGR1): Fast-mode Plus drive
   (20 mA sink) on the pins of I2C1 and I2C3 */
#define SYSCFG_CFGR1 REG(0x40010004u)
#define SYSCFG_CFGR1_I2C1_FMP BIT(20)
#define SYSCFG_CFGR1_I2C3_FMP BIT(22)

/* ---- GPIO (RM0440 chapter "General-purpose I/Os (GPIO)", register map) */
#define GPIOA_BASE 0x48000000u
#define GPIOB_BASE 0x48000400u
#define GPIO_MODER(p) REG((p) + 0x00u)
#define GPIO_OTYPER(p) REG((p) + 0x04u)
#define GPIO_OSPEEDR(p) REG((p) + 0x08u)
#define GPIO_PUPDR(p) REG((p) + 0x0Cu)
#define GPIO_IDR(p) REG((p) + 0x10u)
#define GPIO_BSRR(p) REG((p) + 0x18u)
#define GPIO_AFR(p, pin) REG((p) + 0x20u + 4u * ((pin) >> 3))
#define GPIO_MODE_INPUT 0u
#define GPIO_MODE_OUTPUT 1u
#define GPIO_MODE_AF 2u

/* ---- IWDG (RM0440 §42.4): LSI ~32 kHz, 12-bit reload */
#define IWDG_BASE 0x40003000u
#define IWDG_KR REG(IWDG_BASE + 0x00u)
#define IWDG_PR REG(IWDG_BASE + 0x04u)
#define IWDG_RLR REG(IWDG_BASE + 0x08u)
#define IWDG_SR REG(IWDG_BASE + 0x0Cu)
#define IWDG_KEY_START 0xCCCCu
#define IWDG_KEY_RELOAD 0xAAAAu
#define IWDG_KEY_UNLOCK 0x5555u

/* ---- TIM2, 32-bit general-purpose timer (RM0440 chapter "General-purpose timers (TIM2/TIM3/TIM4/
   TIM5)", register map) */
#define TIM2_BASE 0x40000000u
#define TIM_CR1(t) REG((t) + 0x00u)
#define TIM_DIER(t) REG((t) + 0x0Cu)
#define TIM_SR(t) REG((t) + 0x10u)
#define TIM_EGR(t) REG((t) + 0x14u)
#define TIM_CCMR1(t) REG((t) + 0x18u)
#define TIM_CCMR2(t) REG((t) + 0x1Cu)
#define TIM_CCER(t) REG((t) + 0x20u)
#define TIM_CNT(t) REG((t) + 0x24u)
#define TIM_PSC(t) REG((t) + 0x28u)
#define TIM_ARR(t) REG((t) + 0x2Cu)
#define TIM_CCR(t, ch) REG((t) + 0x34u + 4u * (ch)) /* ch 0..3: CCR1..CCR4 */
#define TIM_CR1_CEN BIT(0)
#define TIM_DIER_UIE BIT(0)
#define TIM_DIER_CCIE(ch) BIT(1 + (ch))
#define TIM_SR_UIF BIT(0)
#define TIM_SR_CCIF(ch) BIT(1 + (ch))
#define TIM_SR_CCOF(ch) BIT(9 + (ch))
#define TIM_EGR_UG BIT(0)
/* CCMRx: CCxS = 01 (input, TIx), ICxF input filter; CCER: CCxE, CCxP and CCxNP both set = both edges */
#define TIM_CCMR_IN_TI(ch, filter) ((1u | ((filter) << 4)) << (8u * ((ch)&1u)))
#define TIM_CCER_BOTH_EDGES(ch) ((BIT(0) | BIT(1) | BIT(3)) << (4u * (ch)))

/* ---- I2C (RM0440 §41 "Inter-integrated circuit (I2C) interface", §41.7 registers; §41.4.7: in
   transmission TXDR is copied to the shift register after the ACK pulse, so TXIS asks for the next
   byte while the current one is on the wire) */
#define I2C1_BASE 0x40005400u
#define I2C3_BASE 0x40007800u
#define I2C_CR1(i) REG((i) + 0x00u)
#define I2C_CR2(i) REG((i) + 0x04u)
#define I2C_OAR1(i) REG((i) + 0x08u)
#define I2C_OAR2(i) REG((i) + 0x0Cu)
#define I2C_TIMINGR(i) REG((i) + 0x10u)
#define I2C_TIMEOUTR(i) REG((i) + 0x14u)
#define I2C_ISR(i) REG((i) + 0x18u)
#define I2C_ICR(i) REG((i) + 0x1Cu)
#define I2C_RXDR(i) REG((i) + 0x24u)
#define I2C_TXDR(i) REG((i) + 0x28u)
#define I2C_CR1_PE BIT(0)
#define I2C_CR1_TXIE BIT(1)
#define I2C_CR1_RXIE BIT(2)
#define I2C_CR1_ADDRIE BIT(3)
#define I2C_CR1_NACKIE BIT(4)
#define I2C_CR1_STOPIE BIT(5)
#define I2C_CR1_ERRIE BIT(7)
#define I2C_CR1_NOSTRETCH BIT(17)
#define I2C_CR2_NACK BIT(15)
#define I2C_OAR_EN BIT(15) /* OA1EN, OA2EN */
#define I2C_OAR_7BIT(a) ((uint32_t)(a) << 1)
#define I2C_OAR2_MSK_MASK (7u << 8) /* OA2MSK: 0 = every bit compared (no mask) */
#define I2C_ISR_TXE BIT(0)
#define I2C_ISR_TXIS BIT(1)
#define I2C_ISR_RXNE BIT(2)
#define I2C_ISR_ADDR BIT(3)
#define I2C_ISR_NACKF BIT(4)
#define I2C_ISR_STOPF BIT(5)
#define I2C_ISR_BERR BIT(8)
#define I2C_ISR_ARLO BIT(9)
#define I2C_ISR_OVR BIT(10)
#define I2C_ISR_TIMEOUT BIT(12)
#define I2C_ISR_DIR BIT(16)
#define I2C_ISR_ADDCODE(isr) (((isr) >> 17) & 0x7Fu)
#define I2C_ICR_ALL (BIT(3) | BIT(4) | BIT(5) | BIT(8) | BIT(9) | BIT(10) | BIT(11) | BIT(12) | BIT(13))
#define I2C_ICR_ADDRCF BIT(3)
#define I2C_ICR_NACKCF BIT(4)
#define I2C_ICR_STOPCF BIT(5)
/* TIMEOUTR: TIMEOUTA (12 bits) with TIDLE = 0 detects SCL low for (TIMEOUTA+1) * 2048 I2CCLK periods */
#define I2C_TIMEOUTR_TIMOUTEN BIT(15)

/* ---- USART (RM0440 §37 "Universal synchronous/asynchronous receiver transmitter (USART/UART)",
   register map) */
#define USART1_BASE 0x40013800u
#define USART2_BASE 0x40004400u
#define USART_CR1(u) REG((u) + 0x00u)
#define USART_CR2(u) REG((u) + 0x04u)
#define USART_CR3(u) REG((u) + 0x08u)
#define USART_BRR(u) REG((u) + 0x0Cu)
#define USART_ISR(u) REG((u) + 0x1Cu)
#define USART_ICR(u) REG((u) + 0x20u)
#define USART_RDR(u) REG((u) + 0x24u)
#define USART_TDR(u) REG((u) + 0x28u)
#define USART_CR1_UE BIT(0)
#define USART_CR1_RE BIT(2)
#define USART_CR1_TE BIT(3)
#define USART_CR1_TXEIE BIT(7)
#define USART_CR1_PCE BIT(10) /* parity on; PS (bit 9) = 0: even */
#define USART_CR1_M0 BIT(12)  /* M1:M0 = 01: 9-bit words (8 data + parity) */
#define USART_CR2_STOP_2 (2u << 12)
#define USART_CR2_TXINV BIT(17)
#define USART_CR3_DMAR BIT(6)
#define USART_CR3_DMAT BIT(7)
#define USART_CR3_OVRDIS BIT(12)
#define USART_ISR_TXE BIT(7)
#define USART_ICR_ERRORS 0x1Fu /* PECF, FECF, NECF, ORECF, IDLECF */

/* ---- DMA1 and DMAMUX1 (RM0440 §12 DMA, §13 DMAMUX; request numbers: DMAMUX table "DMAMUX:
   assignment of multiplexer inputs to resources") */
#define DMA1_BASE 0x40020000u
#define DMA_ISR REG(DMA1_BASE + 0x00u)
#define DMA_IFCR REG(DMA1_BASE + 0x04u)
#define DMA_CCR(ch) REG(DMA1_BASE + 0x08u + 0x14u * ((ch)-1u)) /* ch 1..8 */
#define DMA_CNDTR(ch) REG(DMA1_BASE + 0x0Cu + 0x14u * ((ch)-1u))
#define DMA_CPAR(ch) REG(DMA1_BASE + 0x10u + 0x14u * ((ch)-1u))
#define DMA_CMAR(ch) REG(DMA1_BASE + 0x14u + 0x14u * ((ch)-1u))
#define DMA_CCR_EN BIT(0)
#define DMA_CCR_TCIE BIT(1)
#define DMA_CCR_DIR_M2P BIT(4)
#define DMA_CCR_CIRC BIT(5)
#define DMA_CCR_MINC BIT(7)
#define DMA_ISR_TCIF(ch) BIT(4u * ((ch)-1u) + 1u)
#define DMA_IFCR_ALL(ch) (0xFu << (4u * ((ch)-1u)))
#define DMAMUX_CCR(ch) REG(0x40020800u + 4u * ((ch)-1u)) /* DMA1 channel ch is DMAMUX channel ch-1 */
#define DMAREQ_USART2_RX 26u
#define DMAREQ_USART2_TX 27u

/* ---- FDCAN1 (RM0440 chapter "FD controller area network (FDCAN)"): registers and its message RAM
   (fixed layout: 0x350 bytes per instance at 0x4000A400: 28 standard filters, 8 extended, 3+3 Rx FIFO
   elements, 3 Tx event elements, 3 Tx buffers of 18 words) */
#define FDCAN1_BASE 0x40006400u
#define FDCAN_CCCR REG(FDCAN1_BASE + 0x018u)
#define FDCAN_NBTP REG(FDCAN1_BASE + 0x01Cu)
#define FDCAN_RXGFC REG(FDCAN1_BASE + 0x080u)
#define FDCAN_TXBC REG(FDCAN1_BASE + 0x0C0u)
#define FDCAN_TXFQS REG(FDCAN1_BASE + 0x0C4u)
#define FDCAN_TXBAR REG(FDCAN1_BASE + 0x0CCu)
#define FDCAN_CCCR_INIT BIT(0)
#define FDCAN_CCCR_CCE BIT(1)
#define FDCAN_NBTP_VAL(sjw, brp, seg1, seg2) \
    ((((sjw)-1u) << 25) | (((brp)-1u) << 16) | (((seg1)-1u) << 8) | ((seg2)-1u))
#define FDCAN_RXGFC_REJECT_ALL ((3u << 4) | (3u << 2) | BIT(1) | BIT(0)) /* ANFS, ANFE, RRFS, RRFE */
#define FDCAN_TXFQS_TFQF BIT(21)
#define FDCAN_TXFQS_TFQPI(v) (((v) >> 16) & 3u)
#define FDCAN1_RAM 0x4000A400u
#define FDCAN_RAM_TXBUF(i) (FDCAN1_RAM + 0x278u + 72u * (i))

/* ---- interrupt numbers (RM0440 §14 NVIC, vector table) */
#define IRQ_DMA1_CH2 12
#define IRQ_TIM2 28
#define IRQ_I2C1_EV 31
#define IRQ_I2C1_ER 32
#define IRQ_USART1 37
#define IRQ_I2C3_EV 92
#define IRQ_I2C3_ER 93
#define IRQ_COUNT 102

#endif
