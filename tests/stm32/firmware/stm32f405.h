/* The STM32F405 registers the STM32 tier's test firmwares touch, at their addresses in RM0090 (table 10,
   the register maps of sections 3.9, 5.4, 7.3 and 8.4) and the ARMv7-M ARM (SysTick, DWT). */
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
#define RCC_APB1ENR REG(RCC_BASE + 0x40u)
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
#define RCC_CFGR_PPRE1_DIV4 (0x5u << 10)
#define RCC_CFGR_PPRE2_DIV2 (0x4u << 13)
#define RCC_PLLCFGR_PLLSRC_HSE (1u << 22)
#define RCC_APB1ENR_PWREN (1u << 28)

#define PWR_CR REG(0x40007000u)
#define PWR_CR_VOS (1u << 14)

#define FLASH_ACR REG(0x40023C00u)
#define FLASH_KEYR REG(0x40023C04u)
#define FLASH_CR REG(0x40023C10u)
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

#define SCB_VTOR REG(0xE000ED08u)
#define SCB_CPACR REG(0xE000ED88u)
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)
#define DWT_CTRL REG(0xE0001000u)
#define DWT_CYCCNT REG(0xE0001004u)
#define DEMCR REG(0xE000EDFCu)
#define DEMCR_TRCENA (1u << 24)

#endif
