#!/usr/bin/env bash
# Creates the project's virtualenv (.venv) and installs the Python packages, installing the Debian
# packages a fresh machine lacks first. Called by make; safe to run again (it only does what is missing).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}

"$PYTHON" - <<'PY' || { echo "bootstrap: Python 3.11 or newer is required (PYTHON=$PYTHON)" >&2; exit 1; }
import sys; sys.exit(sys.version_info < (3, 11))
PY

# Debian packages the demo needs, installed only when what they provide is missing (the test tools
# are tools/test-packages.sh's, so `make demo` never waits for toolchains it does not use):
#   python3-venv  ensurepip for `python3 -m venv`
#   python3-dev   Python.h, for mypyc's build of the session's hot modules (rig/compiled.py)
#   chromium      renders the acceptance PDF (`rig run --pdf`, `rig report --pdf`) from its HTML
MISSING=()
if [ ! -x "$VENV/bin/python" ] && ! "$PYTHON" -c 'import ensurepip, venv' 2>/dev/null; then
  MISSING+=(python3-venv)
fi
if ! "$PYTHON" -c 'import os, sys, sysconfig
sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  MISSING+=(python3-dev)
fi
if ! command -v chromium >/dev/null; then MISSING+=(chromium); fi
tools/apt-install.sh bootstrap "${MISSING[@]}"

if [ ! -x "$VENV/bin/python" ]; then
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
# the rig, editable, with pytest and pytest-xdist for its plugin (the README's pytest line runs here)
"$VENV/bin/python" -m pip install -q -e '.[pytest]'
echo "bootstrap: $VENV ready ($("$VENV/bin/python" --version))"
