#!/usr/bin/env bash
# Every test suite, each ending with one summary line; exits non-zero if any failed.
# Usage: tools/run-tests.sh            (does set-up first, then all runners)
#        tools/run-tests.sh --all      (the same, with the Python tests marked slow as well)
# The Python tests run in parallel (pytest-xdist, one worker per core, one test file per worker at
# a time so that a module's fixtures are built once); which tests are marked slow and why is in
# CONTRIBUTING.md.
set -uo pipefail
cd "$(dirname "$0")/.."
pytest_select=(-m "not slow")
for arg in "$@"; do
  case $arg in
    --all) pytest_select=() ;;
    *) echo "usage: tools/run-tests.sh [--all]" >&2; exit 2 ;;
  esac
done
./tools/setup.sh || { echo "SUMMARY setup: FAILED"; exit 1; }

declare -a summary
status=0
run() {  # run NAME CMD...: run one suite, record one summary line
  local name=$1; shift
  local t0=$SECONDS
  echo "==== $name: $*"
  if "$@"; then
    summary+=("PASS  $name ($((SECONDS - t0)) s)")
  else
    summary+=("FAIL  $name ($((SECONDS - t0)) s)"); status=1
  fi
}

run "C unit tests, desktop, ASan+UBSan" ctest --preset desktop
run "C core tests, Cortex-M4 under QEMU" ctest --preset stm32f405
run "Fuzzers, bounded (30 s per target)" ./fuzz/run.sh 30
if [ -d tests/python ] && [ -x .venv/bin/pytest ]; then
  run "Python tests" .venv/bin/pytest -q -n auto --dist loadfile "${pytest_select[@]}" tests/python
fi

echo
for line in "${summary[@]}"; do echo "SUMMARY $line"; done
exit $status
