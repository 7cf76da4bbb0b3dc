#!/bin/sh
# size.sh ELF FLASH_MAX RAM_MAX EEPROM_MAX STACK_MIN: prints the firmware's flash, RAM and EEPROM use
# against the MCU's, from avr-size's section table, and fails when any is over (RAM: when less than
# STACK_MIN bytes would be left for the stack, which the static figures do not include).
set -eu
elf=$1 flash_max=$2 ram_max=$3 eeprom_max=$4 stack_min=$5
avr-size -A "$elf" | awk -v fm="$flash_max" -v rm="$ram_max" -v em="$eeprom_max" -v sm="$stack_min" -v elf="$elf" '
    $1 == ".text" || $1 == ".data" { flash += $2 }
    $1 == ".data" || $1 == ".bss" || $1 == ".noinit" { ram += $2 }
    $1 == ".eeprom" { eeprom += $2 }
    END {
        printf "%s: flash %d of %d bytes (%.1f%%), RAM %d of %d bytes static (%.1f%%, %d left for the stack), EEPROM %d of %d bytes\n",
            elf, flash, fm, 100 * flash / fm, ram, rm, 100 * ram / rm, rm - ram, eeprom, em
        bad = 0
        if (flash > fm) { print "avr: flash over the ATmega2560'"'"'s" > "/dev/stderr"; bad = 1 }
        if (ram + sm > rm) { print "avr: RAM leaves under " sm " bytes for the stack" > "/dev/stderr"; bad = 1 }
        if (eeprom > em) { print "avr: EEPROM over the ATmega2560'"'"'s" > "/dev/stderr"; bad = 1 }
        exit bad
    }'
