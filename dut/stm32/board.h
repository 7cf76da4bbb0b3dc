/* The board the reference FC is built for, chosen at compile time: -DBOARD_BLACKPILL_F411 for the STM32F411
   Black Pill (build/stm32/fc-f411.elf), else the STM32F405 board (build/stm32/fc.elf). Each board's
   header is data: its clock set-up, motor outputs, I2C1 pins and USARTs, as the STM32 tier's board files
   (rig/mcu/boards/) wire them; the sources read only these names. */
#ifndef BOARD_H
#define BOARD_H

#include "stm32f405.h"

#ifdef BOARD_BLACKPILL_F411
#include "board_blackpill_f411.h"
#else
#include "board_f405_gy86.h"
#endif

/* a motor output: its timer's base, channel 1..4, and its pin with the alternate function giving it */
typedef struct {
    uint32_t timer;
    uint8_t channel, port, pin, af;
} board_motor;

/* @pin of @port in alternate function @af (its port's clock on): a motor's timer channel, a USART's TX */
static inline void board_pin_af(uint32_t port, unsigned pin, unsigned af)
{
    RCC_AHB1ENR |= 1u << port;
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2 * pin))) | (GPIO_MODE_AF << (2 * pin));
    volatile uint32_t *afr = pin < 8 ? &GPIO_AFRL(port) : &GPIO_AFRH(port);
    unsigned shift = 4 * (pin % 8);
    *afr = (*afr & ~(0xFu << shift)) | (af << shift);
}

#endif
