#!/usr/bin/env bash
# Build the libFuzzer targets with clang and run each for a bounded time on the kept corpus.
# Usage: fuzz/run.sh [SECONDS_PER_TARGET]   (default 30; CI uses 30, ~1 min with the build)
# Needs clang and libclang-rt-14-dev (Debian 12). The kept corpus fuzz/corpus/ is read, not
# written: new inputs go to build/fuzz/new-<target>/ (copy the good ones into the corpus by hand).
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-30}
build=build/fuzz
if [ ! -f "$build/build.ninja" ]; then
  CC=clang cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPS_FUZZ=ON \
    -DPS_BUILD_TESTS=OFF >/dev/null
fi
cmake --build "$build" --target fuzz_frame fuzz_table fuzz_planted_ub >/dev/null
# Any sanitizer report ends the process with a non-zero status (the targets are also built
# with -fno-sanitize-recover=all); the status, not a grep of the log, decides the run.
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
export ASAN_OPTIONS=halt_on_error=1
status=0
# Proof that it does: the planted overflow must kill fuzz_planted_ub on its trigger input.
planted=$(find "$build" -name fuzz_planted_ub -type f -perm -u+x | head -1)
printf 'UB' > "$build/planted-input"
if "$planted" "$build/planted-input" >"$build/planted.log" 2>&1; then
  echo "[fuzz] FAIL: the planted undefined behaviour did not stop fuzz_planted_ub"; status=1
elif ! grep -q "runtime error: signed integer overflow" "$build/planted.log"; then
  echo "[fuzz] FAIL: fuzz_planted_ub died without the UBSan report"; status=1
else
  echo "[fuzz] planted UB stops the run (as it must)"
fi
# The targets run side by side (each single-threaded, each for its full time): on a 2-core
# machine the stage takes one target's time instead of their sum. Each one's log is printed
# after both end, in order; a target's exit status decides, as before.
targets=(fuzz_frame fuzz_table)
pids=()
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t"
  exe=$(find "$build" -name "$t" -type f -perm -u+x | head -1)
  rm -rf "$build/new-$t" && mkdir -p "$build/new-$t"
  "$exe" -max_total_time="$secs" -max_len=2300 -print_final_stats=1 "$build/new-$t" "fuzz/corpus/$t" \
    >"$build/$t.log" 2>&1 &
  pids+=($!)
done
for i in "${!targets[@]}"; do
  t=${targets[$i]}
  wait "${pids[$i]}" || status=1
  echo "[fuzz] $t for ${secs} s"
  grep -E "^(stat::number_of_executed_units|stat::new_units_added)|ERROR|SUMMARY" "$build/$t.log" || status=1
done
exit $status
