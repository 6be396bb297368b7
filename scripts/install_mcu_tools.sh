#!/usr/bin/env bash
# Install the Cortex-M4 cross toolchain used by `pfbench mcu emulate`.
# Idempotent: returns at once when everything is already present.
#   Debian packages: gcc-arm-none-eabi, libnewlib-arm-none-eabi, libnewlib-dev
#   Python package (project venv): unicorn (the emulator; symbols come from arm-none-eabi-objdump)
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PFBENCH_PYTHON:-}"
if [ -z "$PY" ] && [ -x .venv/bin/python ]; then PY=.venv/bin/python; fi

have_debs() {
  command -v arm-none-eabi-gcc >/dev/null 2>&1 &&
    [ -d /usr/lib/arm-none-eabi/newlib ] &&
    dpkg -s libnewlib-dev >/dev/null 2>&1
}

if have_debs; then
  echo "mcu-tools: arm-none-eabi toolchain present ($(arm-none-eabi-gcc -dumpversion))"
else
  SUDO=""
  if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
      echo "mcu-tools: need root (or sudo) to apt-get install the toolchain" >&2; exit 1; fi
  fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends \
    gcc-arm-none-eabi libnewlib-arm-none-eabi libnewlib-dev >/dev/null
  echo "mcu-tools: installed $(arm-none-eabi-gcc -dumpversion)"
fi

# The emulator (unicorn) is a runtime dependency in pyproject.toml, installed with the venv;
# only repair an existing venv here (never pip-install into the system Python).
if [ -z "$PY" ]; then
  echo "mcu-tools: no .venv yet; unicorn comes with it (make venv)"
elif "$PY" -c "import unicorn" >/dev/null 2>&1; then
  echo "mcu-tools: unicorn present"
else
  "$PY" -m pip install -q "unicorn>=2.0"
  echo "mcu-tools: installed unicorn"
fi
