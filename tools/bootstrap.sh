#!/usr/bin/env bash
# Creates the project's virtualenv (.venv) and installs the Python packages, installing the Debian
# packages a fresh machine lacks first. Called by make; safe to run again (it only does what is missing).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}
DEBIAN_PACKAGES=(python3-venv)   # ensurepip for `python3 -m venv` on Debian

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
  echo "bootstrap: need root (or sudo) to run: $*" >&2; exit 1; fi; }

"$PYTHON" - <<'PY' || { echo "bootstrap: Python 3.11 or newer is required (PYTHON=$PYTHON)" >&2; exit 1; }
import sys; sys.exit(sys.version_info < (3, 11))
PY

if [ ! -x "$VENV/bin/python" ]; then
  if ! "$PYTHON" -c 'import ensurepip, venv' 2>/dev/null; then
    if command -v apt-get >/dev/null; then
      echo "bootstrap: installing Debian packages: ${DEBIAN_PACKAGES[*]}"
      as_root apt-get update -qq
      as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${DEBIAN_PACKAGES[@]}"
    else
      echo "bootstrap: $PYTHON cannot create virtualenvs and apt-get is not available" >&2; exit 1
    fi
  fi
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q -e '.[test]'
echo "bootstrap: $VENV ready ($("$VENV/bin/python" --version))"
