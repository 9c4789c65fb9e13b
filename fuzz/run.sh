#!/usr/bin/env bash
# Build the libFuzzer targets with clang and run each for a bounded time on the kept corpus.
# Usage: fuzz/run.sh [SECONDS_PER_TARGET]   (default 30; CI uses 30, ~1.5 min with the build)
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
cmake --build "$build" --target fuzz_frame fuzz_table >/dev/null
status=0
for t in fuzz_frame fuzz_table; do
  mkdir -p "fuzz/corpus/$t"
  exe=$(find "$build" -name "$t" -type f -perm -u+x | head -1)
  echo "[fuzz] $t for ${secs} s"
  rm -rf "$build/new-$t" && mkdir -p "$build/new-$t"
  "$exe" -max_total_time="$secs" -max_len=2300 -print_final_stats=1 "$build/new-$t" "fuzz/corpus/$t" 2>&1 \
    | grep -E "^(stat::number_of_executed_units|stat::new_units_added)|ERROR|SUMMARY" || status=$?
  [ "${PIPESTATUS[0]}" -eq 0 ] || status=1
done
exit $status
