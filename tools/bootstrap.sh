#!/usr/bin/env bash
# Idempotent setup shared by the README's commands: the Debian packages the firmware side needs
# (AVR toolchain, Arduino core, simavr) and a virtual environment in .venv with this project
# installed in editable mode. Safe to run again: it only does what is missing or out of date.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV="$ROOT/.venv"
APT_PACKAGES=(g++ gcc-avr avr-libc binutils-avr simavr libsimavr-dev libelf-dev arduino-core-avr)

say() { printf 'bootstrap: %s\n' "$*" >&2; }

as_root() {
  if [ "$(id -u)" -eq 0 ]; then "$@"
  elif command -v sudo >/dev/null 2>&1; then sudo "$@"
  else say "need root (or sudo) to install: ${missing[*]}"; exit 1
  fi
}

missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
PYTHON=${PYTHON:-python3}
if ! "$PYTHON" -c 'import venv, ensurepip' >/dev/null 2>&1; then missing+=(python3-venv); fi
if [ ${#missing[@]} -gt 0 ]; then
  say "installing Debian packages: ${missing[*]}"
  as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  # --no-install-recommends: libsimavr's recommends would pull in the Java Arduino IDE.
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
fi

if ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  say "Python 3.11 or newer is needed (found $("$PYTHON" --version 2>&1)); set PYTHON=..."
  exit 1
fi
if [ ! -x "$VENV/bin/python" ]; then
  say "creating virtual environment in $VENV"
  "$PYTHON" -m venv "$VENV"
fi
# Reinstall only when the dependency list or the set of top-level packages changed (an
# editable install maps each top-level package when it is installed).
stamp="$VENV/.delta6-installed"
want=$( { cat "$ROOT/pyproject.toml"; cd "$ROOT" && ls host/*/__init__.py codegen/*/__init__.py 2>/dev/null; } \
  | sha256sum | cut -d' ' -f1)
# The venv with the CPU torch build takes about 1.5 GB (less when only the stamp is out of
# date and torch is in already) and pip builds and unpacks in the temporary directory: a full
# disk would otherwise end in pip's OSError halfway through.
free_mb() { df -Pm "$1" 2>/dev/null | awk 'NR == 2 { print $4 }'; }
need_free() {   # DIR MB
  local avail
  avail=$(free_mb "$1")
  if [ -n "$avail" ] && [ "$avail" -lt "$2" ]; then
    say "only $avail MB free on the disk holding $1; installing the venv needs about $2 MB there"
    exit 1
  fi
}
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  if [ -d "$VENV/lib" ] && compgen -G "$VENV/lib/python3*/site-packages/torch" >/dev/null; then
    need_free "$ROOT" 300
  else
    need_free "$ROOT" 2000
  fi
  need_free "${TMPDIR:-/tmp}" 500
  say "installing the delta6 package, its test dependencies and the training extra into $VENV"
  # --no-cache-dir: pip's wheel cache would keep a second copy of every download.
  "$VENV/bin/python" -m pip install -q --no-cache-dir --upgrade pip >/dev/null
  "$VENV/bin/python" -m pip install -q --no-cache-dir -e "$ROOT[test,train]"
  echo "$want" > "$stamp"
fi
