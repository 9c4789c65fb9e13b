#!/usr/bin/env bash
# Firmware figures as a Markdown table (figure | measured | target | how): M4 instructions
# per call of the production loop (average and worst single call) under QEMU -icount, desktop
# ticks/s, USART image flash and RAM with everything counted.
# Usage: bench/bench_firmware.sh        (builds the stm32f405 and desktop-release presets; ~30 s)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

for preset in stm32f405 desktop-release; do
  [ -f "build/$preset/build.ninja" ] || cmake --preset "$preset" >/dev/null
done
cmake --build --preset stm32f405 >/dev/null
cmake --build --preset desktop-release --target ps_core ps_common >/dev/null

m4dir=build/stm32f405/firmware/boards/stm32f405
fw=$m4dir/playscope-fw.elf
bench_elf=$m4dir/bench/bench-m4.elf

# --- Cortex-M4 under QEMU, -icount shift=3: 1 instruction = 8 ns of virtual time, so the
# 168 MHz SysTick counts 1.344 cycles per instruction and one call is timed to < 1 instruction.
shift=3
out=$(tests/target/run-qemu.sh --icount-shift $shift --timeout 300 "$bench_elf" | tr -d '\r')
grep -q '^BENCH done' <<<"$out" || { echo "bench-m4 did not finish:"; echo "$out"; exit 1; }
core_hz=$(sed -n 's/^BENCH core_hz=//p' <<<"$out")
# cycles -> instructions: 1e9 ns/s / (core_hz * 2^shift ns per instruction)
f=$(awk -v hz="$core_hz" -v s=$shift 'BEGIN { printf "%.9f", 1e9 / (hz * 2^s) }')
field() { awk -v n="$1" -v k="$2" '$1=="BENCH" && $2==n { for (i=3;i<=NF;i++) { split($i,a,"="); if (a[1]==k) print a[2] } }' <<<"$out"; }
# avg / worst instructions per call, the read pair (measured alone) subtracted
avg() { awk -v s="$(field "$1" sum)" -v n="$(field "$1" n)" -v p="$(field "$1" pair)" -v f="$f" 'BEGIN { printf "%.1f", (s / n - p) * f }'; }
worst() { awk -v m="$(field "$1" max)" -v p="$(field "$1" pair)" -v f="$f" 'BEGIN { printf "%.1f", (m - p) * f }'; }
cal=$(awk -v c="$(field calibration_2insn cycles)" -v n="$(field calibration_2insn iterations)" -v f="$f" 'BEGIN { printf "%.2f", c * f / n }')
infos=$(sed -n 's/^BENCH_INFO //p' <<<"$out" | tr '\n' ' ')
verdict() { awk -v v="$1" -v t="$2" 'BEGIN { print (v <= t) ? "met" : "NOT met" }'; }
how="bench-m4.elf under qemu-system-arm -M netduinoplus2 -icount shift=$shift: every call between two SysTick reads, the read pair subtracted; stm32f405 preset (tick sources -O2, rest -Os)"
row() { # name label target_avg target_worst [how]
  local a w; a=$(avg "$1"); w=$(worst "$1")
  local ta="" tw=""
  [ -n "${3:-}" ] && ta="avg <= $3 ($(verdict "$a" "$3")), "
  [ -n "${4:-}" ] && tw="worst <= $4 ($(verdict "$w" "$4"))"
  # at_max: the 0-based call that was the worst, so a reader can tell a reversal from a start-up tick.
  echo "| $2 | $a avg, $w worst (n = $(field "$1" n), worst at call $(field "$1" at_max)) | $ta$tw | ${5:-$how} |"
}

# --- Desktop, desktop-release core (CMAKE_BUILD_TYPE=Release flags). ---
dr=build/desktop-release
release_flags=$(sed -n 's/^CMAKE_C_FLAGS_RELEASE:STRING=//p' $dr/CMakeCache.txt)
cc_desktop=$(sed -n 's/^CMAKE_C_COMPILER:[A-Z]*=//p' $dr/CMakeCache.txt)
mkdir -p $dr/bench
# shellcheck disable=SC2086
cmake --build --preset desktop-release --target ps_app >/dev/null
"$cc_desktop" -std=c11 $release_flags -Ibench -Ifirmware/app -Ifirmware/core -Icommon bench/bench_desktop.c bench/bench_traj.c \
  $dr/firmware/app/libps_app.a $dr/firmware/core/libps_core.a $dr/common/libps_common.a -o $dr/bench/bench-desktop
desk=$($dr/bench/bench-desktop 20000000)
desk_tps=$(sed -n 's/.*ticks_per_s=\([0-9]*\).*/\1/p' <<<"$desk")
desk_ns=$(sed -n 's/.*ns_per_tick=\([0-9.]*\).*/\1/p' <<<"$desk")
cpu=$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)

# --- Sizes of the USART image playscope-fw.elf: everything the chip must hold. ---
sec() { arm-none-eabi-size -A "$fw" | awk -v s="$1" '$1==s {print $2}'; }
flash=0
for s in .isr_vector .text .rodata .ARM.extab .ARM.exidx .init_array .fini_array .data; do
  v=$(sec $s); flash=$((flash + ${v:-0}))
done
data=$(sec .data); bss=$(sec .bss)
sym() { arm-none-eabi-nm "$fw" | awk -v s="$1" '$3==s {print $1}'; }
stack=$((16#$(sym __stack_size)))
heap_min=$(( $(sym __heap_min_size | sed 's/^/16#/;s/^16#$/0/') ))
ram=$((data + bss + heap_min + stack))
probe=$dr/bench/size_probe.o
arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -fno-common -Ifirmware/app -Ifirmware/core -Icommon \
  -c bench/size_probe.c -o "$probe"
psize() { echo $((16#$(arm-none-eabi-nm -S "$probe" | awk -v s="$1" '$4==s {print $2}'))); }
calib_sz=$(psize probe_calib_t); hist=$(psize probe_enc_hist); loop_sz=$(psize probe_psa_loop_t)
kib() { awk -v b="$1" 'BEGIN { printf "%.2f KiB (%d B)", b / 1024, b }'; }

cat <<EOF2
| figure | measured (M4 instructions) | target | how |
|---|---|---|---|
$(row tick_comp_realistic "psa_tick, compensation, realistic: +-30 deg c* reversing every 0.25-0.5 s (random), smoothing on" 120 400)
$(row tick_comp_stress "psa_tick, compensation, stress: c* reversing every 512 ticks" "" 400)
$(row tick_comp_held "psa_tick, compensation, the realistic c* from a 1 kHz host (held 20 ticks; no target, for comparison)" "" "")
$(row tick_exc_realistic "psa_tick, excitation on a ramp (3 mm/s, amplitude 1.3 mm, advance 0.35 mm: a reversal every 0.32/0.43 s), onsets detected" 120 400)
$(row tick_exc_stress "psa_tick, excitation, stress: a reversal every 512/504 ticks (each supersedes the pending onset)" "" 400)
$(row comp_step "of which comp_step (eq. 4 + smoothing), on the realistic c*" "" "")
$(row onset_tick "of which onset_tick (decimated history push, timeout check), same run" "" "")
$(row observe_px "psa_observe_px (= onset_observe_px), 25 Hz frames of the excitation run, incl. the frame that completes an onset" "" "")
$(row observe_deg "psa_observe_deg (= onset_observe_deg), the same excitation seen by a 25 Hz angle sensor (16 deg/mm, 19 of 25 onsets detected), incl. the readings that complete an onset" "" "")
$(row table_commit "table commit: calib_table_crc + calib_load + psa_set_table (the built-in table; flash write aside)" "" "")
$(row b_online_sample_builtin "b_online_sample (on-line B, RLS step + grid rewrite), built-in table's B (33 entries, 9 nodes): on the observation that completes an onset, not in psa_tick" "" "")
$(row b_online_sample_241 "b_online_sample, costliest B grid (241 entries, 16 nodes: the most nodes a grid gets)" "" "")
$(row f_online_reading_builtin "on-line offset and gain of f, one angle reading (psa_f_regressor + f_online_sample), built-in table: on the observation call, not in psa_tick" "" "")
$(row f_online_publish_builtin "f_online_publish (solve + f^-1 rewrite into the spare copy), built-in table: every 12 readings, from the main loop (psa_background), not in psa_tick" "" "")
$(row f_online_step_builtin "f_online learning step (a reading, and the publish when due), built-in table" "" "")
$(row f_online_reading_big "f_online, one angle reading, costliest f^-1 (501 entries, f on 256)" "" "")
$(row f_online_publish_big "f_online_publish, costliest f^-1 (501 entries, f on 256)" "" "")
$(row f_online_step_big "f_online learning step, costliest f^-1 (501 entries, f on 256)" "" "")
$(row tick_pi_realistic "psa_tick, compensation with the transition model (table v2, 16 operators, bench_pi_load), realistic c* as above" 250 600)
$(row tick_pi_stress "psa_tick, compensation with the transition model (16 operators), stress: c* reversing every 512 ticks" 250 600)
$(row comp_step_pi "of which comp_step with the 16 operators (f^-1, PI^-1, B/2 offset, ramp), realistic c*" "" "")
$(row tick_pimap_realistic "psa_tick, compensation with the transition model and a threshold map (table v3, 16 operators on u = g(z), bench_pi_map_load), realistic c* as above" 250 600)
$(row tick_pimap_stress "psa_tick, compensation with the transition model and a threshold map (16 operators), stress: c* reversing every 512 ticks" 250 600)
$(row comp_step_pimap "of which comp_step with the 16 operators and the map (f^-1, PI^-1, g^-1, B/2 offset, ramp), realistic c*" "" "")
$(row tick_pirelax_realistic "psa_tick, compensation with the map model plus the travel-domain relaxation (table v4, bench_pi_relax_load: kappa 0.3, lambda 0.5 mm), realistic c* as above" 250 600)
$(row tick_pirelax_stress "psa_tick, compensation with the map model plus the relaxation, stress: c* reversing every 512 ticks" 250 600)
$(row comp_step_pirelax "of which comp_step with the operators, the map and the relaxation's inverse (f^-1, R^-1, PI^-1, g^-1, B/2 offset, ramp), realistic c*" "" "")
| instruction-count calibration (subs+bne loop) | $cal per iteration | 2.00 | same counter, a loop of exactly 2 instructions |
| counts of the runs | $infos | | BENCH_INFO lines of bench-m4.elf |
| desktop throughput of psa_tick (realistic compensation) | $desk_tps ticks/s ($desk_ns ns/tick) | | bench-desktop, best of 5 x 20e6 ticks, desktop-release flags \`$release_flags\`, $cpu |
| playscope-fw.elf flash, everything | $(kib $flash) | <= 24 KiB ($(verdict "$flash" 24576)) | arm-none-eabi-size -A: .isr_vector + .text + .rodata + .ARM.extab/.exidx + .init/.fini_array + .data initialisers |
| playscope-fw.elf RAM, everything | $(kib $ram) | <= 24 KiB ($(verdict "$ram" 24576)) | .data $data + .bss $bss (tables, history, loop) + heap minimum $heap_min + stack reservation $stack (__stack_size; high-water mark on the status line) |
| of which calib_t (table entries + derived f^-1, z_up, z_down, g^-1) | $(kib $calib_sz) | | sizeof(calib_t) (bench/size_probe.c, nm -S) |
| b_online_t (on-line B: RAM grid, theta, P), when an image enables it | $(kib $(psize probe_b_online_t)) | | sizeof(b_online_t) (bench/size_probe.c) |
| f_online_t (on-line offset and gain of f: two f^-1 copies, five sums), when an image enables it | $(kib $(psize probe_f_online_t)) | | sizeof(f_online_t) (bench/size_probe.c) |
| of which psa_loop_t (incl. onset_t with the encoder history) | $(kib $loop_sz) | | sizeof(psa_loop_t); enc_hist_t alone $(kib $hist) |
EOF2
