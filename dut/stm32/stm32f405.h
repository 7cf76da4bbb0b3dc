/* The STM32F405 registers the STM32 tier's test firmwares and the reference FC (dut/stm32) touch, at their
   addresses in RM0090 (table 10, the register maps of sections 3.9, 5.4, 7.3, 8.4 and 30.6) and the
   ARMv7-M ARM (SysTick, DWT). The STM32F411 has these at the same addresses (RM0383), less what it lacks
   (TIM6-8, TIM12-14, USART3, UART4/5, GPIO F/G/I). */
#ifndef STM32F405_H
#define STM32F405_H

#include <stdint.h>

#define REG(addr) (*(volatile uint32_t *)(addr))

#define RCC_BASE 0x40023800u
#define RCC_CR REG(RCC_BASE + 0x00u)
#define RCC_PLLCFGR REG(RCC_BASE + 0x04u)
#define RCC_CFGR REG(RCC_BASE + 0x08u)
#define RCC_AHB1RSTR REG(RCC_BASE + 0x10u)
#define RCC_CIR REG(RCC_BASE + 0x0Cu)
#define RCC_AHB1ENR REG(RCC_BASE + 0x30u)
#define RCC_APB1RSTR REG(RCC_BASE + 0x20u)
#define RCC_APB1ENR REG(RCC_BASE + 0x40u)
#define RCC_APB2ENR REG(RCC_BASE + 0x44u)
#define RCC_APB1LPENR REG(RCC_BASE + 0x60u)
#define RCC_CSR REG(RCC_BASE + 0x74u)
#define RCC_CR_HSION (1u << 0)
#define RCC_CR_HSIRDY (1u << 1)
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_CFGR_SW 0x3u
#define RCC_CFGR_SW_HSE 0x1u
#define RCC_CFGR_SW_PLL 0x2u
#define RCC_CFGR_SWS 0xCu
#define RCC_CFGR_SWS_PLL 0x8u
#define RCC_CFGR_PPRE1_DIV2 (0x4u << 10)
#define RCC_CFGR_PPRE1_DIV4 (0x5u << 10)
#define RCC_CFGR_PPRE1_DIV8 (0x6u << 10)
#define RCC_CFGR_PPRE1 (0x7u << 10)
#define RCC_CFGR_PPRE2_DIV2 (0x4u << 13)
#define RCC_PLLCFGR_PLLSRC_HSE (1u << 22)
#define RCC_APB1ENR_PWREN (1u << 28)
#define RCC_APB1ENR_I2C1EN (1u << 21)
#define RCC_AHB1ENR_GPIOBEN (1u << 1)

#define PWR_CR REG(0x40007000u)
#define PWR_CR_VOS (1u << 14)

#define FLASH_ACR REG(0x40023C00u)
#define FLASH_KEYR REG(0x40023C04u)
#define FLASH_CR REG(0x40023C10u)
#define FLASH_SR REG(0x40023C0Cu)
#define FLASH_KEY1 0x45670123u
#define FLASH_KEY2 0xCDEF89ABu
#define FLASH_CR_PG (1u << 0)
#define FLASH_CR_SER (1u << 1)
#define FLASH_CR_MER (1u << 2)
#define FLASH_CR_SNB(n) ((uint32_t)(n) << 3)
#define FLASH_CR_PSIZE(n) ((uint32_t)(n) << 8) /* 0 x8, 1 x16, 2 x32, 3 x64 */
#define FLASH_CR_STRT (1u << 16)
#define FLASH_CR_EOPIE (1u << 24)
#define FLASH_CR_LOCK (1u << 31)
#define FLASH_SR_EOP (1u << 0)
#define FLASH_SR_PGAERR (1u << 5)
#define FLASH_SR_PGPERR (1u << 6)
#define FLASH_SR_PGSERR (1u << 7)
#define FLASH_SR_BSY (1u << 16)
#define FLASH_IRQ 4u
#define IWDG_KR REG(0x40003000u)
#define IWDG_PR REG(0x40003004u)
#define IWDG_RLR REG(0x40003008u)
#define IWDG_SR REG(0x4000300Cu)
#define RCC_CSR_RMVF (1u << 24)
#define WWDG_CR REG(0x40002C00u)
#define WWDG_CFR REG(0x40002C04u)
#define WWDG_SR REG(0x40002C08u)
#define RCC_APB1ENR_WWDGEN (1u << 11)
#define FLASH_ACR_LATENCY_5WS 5u
#define FLASH_ACR_PRFTEN (1u << 8)
#define FLASH_ACR_ICEN (1u << 9)
#define FLASH_ACR_DCEN (1u << 10)

#define GPIO_BASE(port) (0x40020000u + 0x400u * (port))
#define GPIO_MODER(port) REG(GPIO_BASE(port) + 0x00u)
#define GPIO_OTYPER(port) REG(GPIO_BASE(port) + 0x04u)
#define GPIO_OSPEEDR(port) REG(GPIO_BASE(port) + 0x08u)
#define GPIO_PUPDR(port) REG(GPIO_BASE(port) + 0x0Cu)
#define GPIO_IDR(port) REG(GPIO_BASE(port) + 0x10u)
#define GPIO_ODR(port) REG(GPIO_BASE(port) + 0x14u)
#define GPIO_BSRR(port) REG(GPIO_BASE(port) + 0x18u)
#define GPIO_LCKR(port) REG(GPIO_BASE(port) + 0x1Cu)
#define GPIO_AFRL(port) REG(GPIO_BASE(port) + 0x20u)
#define GPIO_AFRH(port) REG(GPIO_BASE(port) + 0x24u)
#define PORT_A 0u
#define PORT_B 1u
#define PORT_D 3u
#define PORT_E 4u
#define PORT_C 2u

/* I2C1 (RM0090 27.6, table 133) */
#define I2C1_BASE 0x40005400u
#define I2C1_CR1 REG(I2C1_BASE + 0x00u)
#define I2C1_CR2 REG(I2C1_BASE + 0x04u)
#define I2C1_OAR1 REG(I2C1_BASE + 0x08u)
#define I2C1_DR REG(I2C1_BASE + 0x10u)
#define I2C1_SR1 REG(I2C1_BASE + 0x14u)
#define I2C1_SR2 REG(I2C1_BASE + 0x18u)
#define I2C1_CCR REG(I2C1_BASE + 0x1Cu)
#define I2C1_TRISE REG(I2C1_BASE + 0x20u)
#define I2C_CR1_PE (1u << 0)
#define I2C_CR1_START (1u << 8)
#define I2C_CR1_STOP (1u << 9)
#define I2C_CR1_ACK (1u << 10)
#define I2C_CR1_POS (1u << 11)
#define I2C_CR1_SWRST (1u << 15)
#define I2C_CR2_ITERREN (1u << 8)
#define I2C_CR2_ITEVTEN (1u << 9)
#define I2C_CR2_ITBUFEN (1u << 10)
#define I2C_SR1_SB (1u << 0)
#define I2C_SR1_ADDR (1u << 1)
#define I2C_SR1_BTF (1u << 2)
#define I2C_SR1_RXNE (1u << 6)
#define I2C_SR1_TXE (1u << 7)
#define I2C_SR1_AF (1u << 10)
#define I2C_SR2_MSL (1u << 0)
#define I2C_SR2_BUSY (1u << 1)
#define I2C_SR2_TRA (1u << 2)
#define I2C_CCR_FS (1u << 15)
#define I2C1_EV_IRQ 31u
#define I2C1_ER_IRQ 32u

/* The timers (RM0090 table 10; the registers of 17.4.21, 18.4.19, 19.4.13, 19.5.12, 20.4.9) */
#define TIM1_BASE 0x40010000u
#define TIM2_BASE 0x40000000u
#define TIM3_BASE 0x40000400u
#define TIM4_BASE 0x40000800u
#define TIM5_BASE 0x40000C00u
#define TIM6_BASE 0x40001000u
#define TIM7_BASE 0x40001400u
#define TIM8_BASE 0x40010400u
#define TIM9_BASE 0x40014000u
#define TIM10_BASE 0x40014400u
#define TIM11_BASE 0x40014800u
#define TIM12_BASE 0x40001800u
#define TIM13_BASE 0x40001C00u
#define TIM14_BASE 0x40002000u
#define TIM_CR1(t) REG((t) + 0x00u)
#define TIM_CR2(t) REG((t) + 0x04u)
#define TIM_SMCR(t) REG((t) + 0x08u)
#define TIM_DIER(t) REG((t) + 0x0Cu)
#define TIM_SR(t) REG((t) + 0x10u)
#define TIM_EGR(t) REG((t) + 0x14u)
#define TIM_CCMR1(t) REG((t) + 0x18u)
#define TIM_CCMR2(t) REG((t) + 0x1Cu)
#define TIM_CCER(t) REG((t) + 0x20u)
#define TIM_CNT(t) REG((t) + 0x24u)
#define TIM_PSC(t) REG((t) + 0x28u)
#define TIM_ARR(t) REG((t) + 0x2Cu)
#define TIM_RCR(t) REG((t) + 0x30u)
#define TIM_CCR(t, ch) REG((t) + 0x30u + 4u * (ch)) /* ch 1..4 */
#define TIM_BDTR(t) REG((t) + 0x44u)
#define TIM_CR1_CEN (1u << 0)
#define TIM_CR1_OPM (1u << 3)
#define TIM_CR1_DIR (1u << 4)
#define TIM_CR1_CMS_CENTER1 (1u << 5)
#define TIM_CR1_ARPE (1u << 7)
#define TIM_SR_UIF (1u << 0)
#define TIM_SR_TIF (1u << 6)
#define TIM_SR_CCIF(ch) (1u << (ch))        /* ch 1..4 */
#define TIM_SR_CCOF(ch) (1u << (8u + (ch))) /* ch 1..4 */
#define TIM_DIER_UIE (1u << 0)
#define TIM_DIER_CCIE(ch) (1u << (ch))
#define TIM_EGR_UG (1u << 0)
#define TIM_CR1_UDIS (1u << 1)
#define TIM_CR1_URS (1u << 2)
#define TIM_CCMR_TOGGLE (3u << 4)
#define TIM_CCMR_FORCE_LOW (4u << 4)
#define TIM_CCMR_FORCE_HIGH (5u << 4)
#define TIM_CCMR_PWM1 (6u << 4)
#define TIM_CCMR_PWM2 (7u << 4)
#define TIM_CCMR_OCPE (1u << 3)
#define TIM_CCMR_ICPSC_DIV2 (1u << 2)
#define TIM_CCMR_IC_TI_OWN 1u   /* CCxS = 01: ICx on its own TIx */
#define TIM_CCMR_IC_TI_OTHER 2u /* CCxS = 10: ICx on the pair's other TI */
#define TIM_CCER_E(ch) (1u << (4u * ((ch)-1u)))
#define TIM_CCER_P(ch) (2u << (4u * ((ch)-1u)))
#define TIM_CCER_NE(ch) (4u << (4u * ((ch)-1u)))
#define TIM_BDTR_MOE (1u << 15)
/* NVIC lines (RM0090 table 61) */
#define TIM1_UP_TIM10_IRQ 25u
#define TIM1_CC_IRQ 27u
#define TIM4_IRQ 30u
#define TIM8_UP_TIM13_IRQ 44u
#define GPIO_MODE_AF 2u

/* USART1 and USART6 on APB2, USART2/3 on APB1 (RM0090 table 10; registers 30.6) */
#define USART1_BASE 0x40011000u
#define USART2_BASE 0x40004400u
#define USART3_BASE 0x40004800u
#define USART6_BASE 0x40011400u
#define USART_SR(u) REG((u) + 0x00u)
#define USART_DR(u) REG((u) + 0x04u)
#define USART_BRR(u) REG((u) + 0x08u)
#define USART_CR1(u) REG((u) + 0x0Cu)
#define USART_CR2(u) REG((u) + 0x10u)
#define USART_SR_PE (1u << 0)
#define USART_SR_FE (1u << 1)
#define USART_SR_ORE (1u << 3)
#define USART_SR_IDLE (1u << 4)
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TXE (1u << 7)
#define USART_CR1_RE (1u << 2)
#define USART_CR1_TE (1u << 3)
#define USART_CR1_IDLEIE (1u << 4)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TXEIE (1u << 7)
#define USART_CR1_PCE (1u << 10)
#define USART_CR1_M (1u << 12)
#define USART_CR1_UE (1u << 13)
#define USART_CR2_STOP_2 (2u << 12)
#define USART_CR3(u) REG((u) + 0x14u)
#define USART_CR3_DMAR (1u << 6)
#define USART_CR3_DMAT (1u << 7)
#define RCC_APB2ENR_USART1EN (1u << 4)
#define RCC_APB2ENR_USART6EN (1u << 5)
#define RCC_APB1ENR_USART2EN (1u << 17)
#define USART1_IRQ 37u
#define USART2_IRQ 38u
#define USART6_IRQ 71u

/* DMA1 and DMA2 (RM0090 10.5): LISR/HISR and LIFCR/HIFCR, a stream's SxCR, SxNDTR, SxPAR, SxM0AR */
#define DMA1_BASE 0x40026000u
#define DMA2_BASE 0x40026400u
#define DMA_ISR(d, n) REG((d) + 0x00u + 4u * ((n) / 4u)) /* stream n's flags: LISR for 0-3, HISR for 4-7 */
#define DMA_IFCR(d, n) REG((d) + 0x08u + 4u * ((n) / 4u))
#define DMA_FLAGS_SHIFT(n) ((const uint8_t[]){ 0u, 6u, 16u, 22u }[(n) % 4u])
#define DMA_FLAGS_ALL 0x3Du /* FEIF, DMEIF, TEIF, HTIF, TCIF */
#define DMA_TCIF (1u << 5)
#define DMA_SCR(d, n) REG((d) + 0x10u + 0x18u * (n))
#define DMA_SNDTR(d, n) REG((d) + 0x14u + 0x18u * (n))
#define DMA_SPAR(d, n) REG((d) + 0x18u + 0x18u * (n))
#define DMA_SM0AR(d, n) REG((d) + 0x1Cu + 0x18u * (n))
#define DMA_SCR_EN (1u << 0)
#define DMA_SCR_TCIE (1u << 4)
#define DMA_SCR_M2P (1u << 6)
#define DMA_SCR_CIRC (1u << 8)
#define DMA_SCR_MINC (1u << 10)
#define DMA_SCR_CHSEL(c) ((uint32_t)(c) << 25)
#define RCC_AHB1ENR_DMA1EN (1u << 21)
#define RCC_AHB1ENR_DMA2EN (1u << 22)

#define NVIC_ISER(n) REG(0xE000E100u + 4u * (n))
#define NVIC_ICER(n) REG(0xE000E180u + 4u * (n))

#define SCB_VTOR REG(0xE000ED08u)
#define SCB_AIRCR REG(0xE000ED0Cu)
#define SYST_CSR_ENABLE_TICKINT_CORE 0x7u               /* ENABLE, TICKINT, CLKSOURCE = the core clock */
#define SCB_AIRCR_SYSRESETREQ (0x05FAu << 16 | 1u << 2) /* VECTKEY and SYSRESETREQ */
#define SCB_CPACR REG(0xE000ED88u)
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)
#define DWT_CTRL REG(0xE0001000u)
#define DWT_CYCCNT REG(0xE0001004u)
#define DEMCR REG(0xE000EDFCu)
#define DEMCR_TRCENA (1u << 24)

#endif
