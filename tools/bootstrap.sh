#!/usr/bin/env bash
# Creates the project's virtualenv (.venv) and installs the Python packages, installing the Debian
# packages a fresh machine lacks first. Called by make; safe to run again (it only does what is missing).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
  echo "bootstrap: need root (or sudo) to run: $*" >&2; exit 1; fi; }

"$PYTHON" - <<'PY' || { echo "bootstrap: Python 3.11 or newer is required (PYTHON=$PYTHON)" >&2; exit 1; }
import sys; sys.exit(sys.version_info < (3, 11))
PY

# Debian packages, installed only when what they provide is missing:
#   python3-venv  ensurepip for `python3 -m venv`
#   i2c-tools     i2cdetect/i2cget/i2cset/i2ctransfer, the third-party clients `rig exec` is tested with
#   python3-dev   Python.h, for mypyc's build of the session's hot modules (rig/compiled.py)
#   clang-format  the C style check of `make lint` (.clang-format)
#   chromium      renders the acceptance PDF (`rig run --pdf`, `rig report --pdf`) from its HTML, and
#                 drives the screenshot test of report.html (Playwright with executable_path; Playwright
#                 never downloads a browser of its own)
#   poppler-utils pdftotext and pdftoppm: the tests read the PDF's text; the docs' page image
#   gcc-arm-none-eabi, libnewlib-arm-none-eabi
#                 the bridge firmware for the STM32G431 (`make firmware`) and the bridge core's tests
#                 cross-built for a Cortex-M4 (newlib's C library and its semihosting rdimon specs)
#   qemu-system-arm
#                 runs those tests on an emulated Cortex-M4 (mps2-an386) in `make test`: what the host
#                 and the MCU compute must agree byte for byte
MISSING=()
if [ ! -x "$VENV/bin/python" ] && ! "$PYTHON" -c 'import ensurepip, venv' 2>/dev/null; then
  MISSING+=(python3-venv)
fi
if ! PATH="$PATH:/usr/sbin:/sbin" command -v i2ctransfer >/dev/null; then MISSING+=(i2c-tools); fi
if ! "$PYTHON" -c 'import os, sys, sysconfig
sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  MISSING+=(python3-dev)
fi
if ! command -v clang-format >/dev/null; then MISSING+=(clang-format); fi
if ! command -v chromium >/dev/null; then MISSING+=(chromium); fi
if ! command -v pdftotext >/dev/null || ! command -v pdftoppm >/dev/null; then MISSING+=(poppler-utils); fi
if ! command -v arm-none-eabi-gcc >/dev/null; then MISSING+=(gcc-arm-none-eabi); fi
if [ ! -e /usr/lib/arm-none-eabi/newlib/thumb/v7e-m+fp/hard/librdimon.a ]; then MISSING+=(libnewlib-arm-none-eabi); fi
if ! command -v qemu-system-arm >/dev/null; then MISSING+=(qemu-system-arm); fi
if [ ${#MISSING[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null; then
    echo "bootstrap: installing Debian packages: ${MISSING[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${MISSING[@]}"
  else
    echo "bootstrap: missing ${MISSING[*]} and apt-get is not available; install them by hand" >&2; exit 1
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q -e '.[test]'
echo "bootstrap: $VENV ready ($("$VENV/bin/python" --version))"
