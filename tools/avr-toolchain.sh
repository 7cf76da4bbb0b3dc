#!/usr/bin/env bash
# Installs what the MCU tier and the AVR firmware need, only when missing, with apt-get (sudo when not
# root). Kept apart from bootstrap.sh so that `make demo` never waits for toolchains it does not use;
# `make test` and `make avr` call it.
#   gcc-avr, avr-libc  avr-gcc and the C library: the AVR reference FC and the MCU tier's test firmwares
#   libsimavr-dev      simavr 1.6, the engine that runs an AVR image in the MCU tier (docs/mcu.md)
set -euo pipefail
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
  echo "avr-toolchain: need root (or sudo) to run: $*" >&2; exit 1; fi; }
MISSING=()
if ! command -v avr-gcc >/dev/null; then MISSING+=(gcc-avr); fi
if [ ! -e /usr/lib/avr/include/avr/io.h ]; then MISSING+=(avr-libc); fi
if [ ! -e /usr/include/simavr/sim_avr.h ]; then MISSING+=(libsimavr-dev); fi
if [ ${#MISSING[@]} -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "avr-toolchain: missing ${MISSING[*]} and apt-get is not available; install them by hand" >&2; exit 1
  fi
  echo "avr-toolchain: installing Debian packages: ${MISSING[*]}"
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${MISSING[@]}"
fi
