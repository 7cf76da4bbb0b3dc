#!/usr/bin/env bash
# Installs what `make test` needs beyond the demo: the test extra's Python packages, and these Debian
# packages when what they provide is missing (tools/avr-toolchain.sh brings the AVR ones):
#   i2c-tools     i2cdetect/i2cget/i2cset/i2ctransfer, the third-party clients `rig exec` is tested with
#   clang-format  the C style check of `make lint` (.clang-format)
#   poppler-utils pdftotext and pdftoppm: the tests read the acceptance PDF's text; the docs' page image
#   gcc-arm-none-eabi, libnewlib-arm-none-eabi
#                 the bridge firmware for the STM32G431 (`make firmware`) and the bridge core's tests
#                 cross-built for a Cortex-M4 (newlib's C library and its semihosting rdimon specs)
#   qemu-system-arm
#                 runs those tests on an emulated Cortex-M4 (mps2-an386): what the host and the MCU
#                 compute must agree byte for byte
#   iproute2      ip netns and veth: the farm's test across hosts makes network namespaces
#   openssl       the farm's TLS test makes a self-signed certificate with it
#   bubblewrap    bwrap: the sandbox the service runs every DUT in (rig/sandbox.py, docs/service.md)
set -euo pipefail
cd "$(dirname "$0")/.."
MISSING=()
if ! PATH="$PATH:/usr/sbin:/sbin" command -v i2ctransfer >/dev/null; then MISSING+=(i2c-tools); fi
if ! command -v clang-format >/dev/null; then MISSING+=(clang-format); fi
if ! command -v pdftotext >/dev/null || ! command -v pdftoppm >/dev/null; then MISSING+=(poppler-utils); fi
if ! command -v arm-none-eabi-gcc >/dev/null; then MISSING+=(gcc-arm-none-eabi); fi
if [ ! -e /usr/lib/arm-none-eabi/newlib/thumb/v7e-m+fp/hard/librdimon.a ]; then MISSING+=(libnewlib-arm-none-eabi); fi
if ! command -v qemu-system-arm >/dev/null; then MISSING+=(qemu-system-arm); fi
if ! PATH="$PATH:/usr/sbin:/sbin" command -v ip >/dev/null; then MISSING+=(iproute2); fi
if ! command -v openssl >/dev/null; then MISSING+=(openssl); fi
if ! command -v bwrap >/dev/null; then MISSING+=(bubblewrap); fi
tools/apt-install.sh test-packages "${MISSING[@]}"
tools/avr-toolchain.sh
# the test suite's Python packages (pyproject.toml's [test] extra) into the virtualenv bootstrap.sh made
.venv/bin/python -m pip install -q -e '.[test]'
