#!/usr/bin/env bash
# Installs what the MCU tier and the AVR firmware need, only when missing, with apt-get (sudo when not
# root). Kept apart from bootstrap.sh so that `make demo` never waits for toolchains it does not use;
# `make test` and `make avr` call it.
#   gcc-avr, avr-libc  avr-gcc and the C library: the AVR reference FC and the MCU tier's test firmwares
#   libsimavr-dev      simavr 1.6, the engine that runs an AVR image in the MCU tier (docs/mcu.md)
#   simavr             its command-line runner: the AVR firmware's start-up tests run it without the rig
set -euo pipefail
cd "$(dirname "$0")/.."
MISSING=()
if ! command -v avr-gcc >/dev/null; then MISSING+=(gcc-avr); fi
if [ ! -e /usr/lib/avr/include/avr/io.h ]; then MISSING+=(avr-libc); fi
if [ ! -e /usr/include/simavr/sim_avr.h ]; then MISSING+=(libsimavr-dev); fi
if ! command -v simavr >/dev/null; then MISSING+=(simavr); fi
tools/apt-install.sh avr-toolchain "${MISSING[@]}"
