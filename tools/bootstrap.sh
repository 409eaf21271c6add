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
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  say "installing the delta6 package, its test dependencies and the training extra into $VENV"
  "$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null
  "$VENV/bin/python" -m pip install -q -e "$ROOT[test,train]"
  echo "$want" > "$stamp"
fi
