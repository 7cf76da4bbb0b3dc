# The devices of the rig's qemu-system-arm (configure --without-default-devices): the rig's STM32F405
# machine, the Netduino Plus 2 (QEMU's own F405 board, for comparison) and semihosting
CONFIG_RIG_STM32F405=y
CONFIG_NETDUINOPLUS2=y
CONFIG_SEMIHOSTING=y
CONFIG_ARM_COMPATIBLE_SEMIHOSTING=y
