#!/usr/bin/env bash
# tools/apt-install.sh WHO PKG...: installs Debian packages with apt-get (sudo when not root); nothing
# when none is named. WHO prefixes the messages. The callers decide what is missing.
set -euo pipefail
who=$1; shift
[ $# -gt 0 ] || exit 0
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
  echo "$who: need root (or sudo) to run: $*" >&2; exit 1; fi; }
if ! command -v apt-get >/dev/null; then
  echo "$who: missing $* and apt-get is not available; install them by hand" >&2; exit 1
fi
echo "$who: installing Debian packages: $*"
as_root apt-get update -qq
as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@"
