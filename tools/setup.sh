#!/usr/bin/env bash
# One-time (idempotent) set-up on a fresh Debian 12: apt packages, a Python venv with the
# host installed, and the firmware builds. Safe to re-run; skips what is already there.
# Usage: tools/setup.sh [--main]   (--main: only the desktop-release build the main job uses)
set -euo pipefail
presets=(desktop desktop-release stm32f405)
[ "${1:-}" = "--main" ] && presets=(desktop-release)
cd "$(dirname "$0")/.."

APT_PKGS=(cmake ninja-build gcc libcmocka-dev gcc-arm-none-eabi libnewlib-arm-none-eabi
          qemu-system-arm libusb-1.0-0-dev umockdev libumockdev-dev pkg-config
          python3-venv clang libclang-rt-14-dev)
missing=()
for p in "${APT_PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "[setup] apt-get install ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get install -y -q "${missing[@]}" >/dev/null 2>&1 \
    || { $SUDO apt-get update -q >/dev/null && $SUDO apt-get install -y -q "${missing[@]}" >/dev/null; }
fi

if [ -f host/pyproject.toml ]; then
  if [ ! -x .venv/bin/python ]; then
    echo "[setup] python venv .venv"
    python3 -m venv .venv
    .venv/bin/pip install -q --upgrade pip
  fi
  stamp=.venv/.host-installed
  if [ ! -f "$stamp" ] || [ host/pyproject.toml -nt "$stamp" ]; then
    echo "[setup] pip install -e host[dev]"
    .venv/bin/pip install -q -e "host[dev]"
    touch "$stamp"
  fi
fi

for preset in "${presets[@]}"; do
  [ -f "build/$preset/build.ninja" ] || cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" >/dev/null
done
echo "[setup] done"
