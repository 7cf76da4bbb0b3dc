"""The MCU tier's engine: an AVR image run by simavr, the chip core on its TWI (docs/mcu.md)."""
