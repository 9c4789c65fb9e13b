#!/usr/bin/env bash
# Fail if a per-tick object of ps_core references a software divide, a float routine or the heap.
# Usage: tools/check-tick-objects.sh [--nm NM] [--tick-sources "lut.c playop.c ..."] [OBJECT...]
#   Without objects: the ARM build's ps_core objects in build/stm32f405, and the tick
#   sources from PS_CORE_TICK_SOURCES in firmware/core/CMakeLists.txt. Objects whose
#   source is not a tick source (loader, init-time conversions) are skipped: they may divide.
# Like Klipper's scripts/check-software-div.sh, on undefined symbols (nm -u): on the
# Cortex-M4 a 32-bit divide is one UDIV/SDIV instruction, anything else is a libgcc call.
# Also fails on FPU instructions in those objects (objdump -d beside NM).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)

nm=arm-none-eabi-nm
tick_sources=""
while [ $# -gt 0 ]; do
  case $1 in
    --nm) nm=$2; shift 2 ;;
    --tick-sources) tick_sources=$2; shift 2 ;;
    -h|--help) sed -n '2,8p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
if [ -z "$tick_sources" ]; then
  tick_sources=$(sed -n 's/^set(PS_CORE_TICK_SOURCES \(.*\))$/\1/p' "$repo/firmware/core/CMakeLists.txt")
fi
tick_sources=${tick_sources//;/ }
objdump=${nm%nm}objdump
[ -n "$tick_sources" ] || { echo "check-tick-objects: no tick sources found" >&2; exit 2; }

objects=("$@")
if [ ${#objects[@]} -eq 0 ]; then
  shopt -s nullglob
  objects=("$repo"/build/stm32f405/firmware/core/CMakeFiles/ps_core.dir/*.o*)
fi

# Forbidden undefined symbols (ERE):
#   __aeabi_*div*, __aeabi_[u]ldivmod   software divides (64-bit, or any without UDIV)
#   __aeabi_f*, __aeabi_d*, __aeabi_[ul]?[il]2[fd], __aeabi_*2[fd]  float/double runtime
#   __*sf*, __*df*                      GCC names of the same soft-float helpers
#   malloc/free/calloc/realloc          the tick must not touch the heap
#   libm and float printf helpers       sqrt, floor, ... via their usual names
forbidden='^(__aeabi_[a-z]*div[a-z0-9]*|__aeabi_[ul]?ldivmod|__aeabi_[fd][a-z0-9]+|__aeabi_[ul]?[il]2[fd]|__aeabi_[a-z0-9]+2[fd]|__[a-z]*[sd]f[0-9a-z]*|__(u)?div[sd]i3|__(u)?mod[sd]i3|malloc|free|calloc|realloc|_malloc_r|_free_r|(sqrt|floor|ceil|round|lround|fabs|exp|log|pow|sin|cos|tan|atan2?)f?)$'

status=0
checked=0
for src in $tick_sources; do
  found=""
  for obj in "${objects[@]}"; do
    case $(basename "$obj") in
      "$src.o"|"$src.obj") found=$obj ;;
    esac
  done
  if [ -z "$found" ]; then
    echo "check-tick-objects: FAIL: no object for tick source $src (build the stm32f405 preset first)"
    status=1
    continue
  fi
  # nm failing (missing or foreign object) must fail the check, not pass it silently.
  if ! undefined=$("$nm" -u "$found"); then
    echo "check-tick-objects: FAIL: $nm could not read $found"
    status=1
    continue
  fi
  bad=$(awk '{print $NF}' <<<"$undefined" | grep -E "$forbidden" || true)
  checked=$((checked + 1))
  if [ -n "$bad" ]; then
    echo "check-tick-objects: FAIL: $src references: $(echo "$bad" | tr '\n' ' ')"
    status=1
  fi
  # With -mfloat-abi=hard single-precision maths compiles to inline FPU instructions, not
  # calls: look for them too, since the tick is integer-only (and FPU use costs a lazy
  # context save in every interrupt).
  # Every FPU instruction of the M4 (vadd, vmov, vldr, vpush, ...) starts with v; no
  # integer one does. objdump puts a tab before each mnemonic.
  fpu=$("$objdump" -d "$found" | grep -cE "$(printf '\t')v[a-z]" || true)
  if [ "$fpu" != 0 ]; then
    echo "check-tick-objects: FAIL: $src contains $fpu FPU instructions"
    status=1
  fi
done
if [ $status -eq 0 ]; then
  echo "check-tick-objects: OK: $checked per-tick objects ($tick_sources) free of software divide, float and heap calls and of FPU instructions"
fi
exit $status
