#!/usr/bin/env bash
# Firmware figures as a Markdown table (figure | measured | target | how): M4 instructions
# per control tick under QEMU -icount, desktop ticks/s, USART image flash and RAM.
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

# --- Cortex-M4 under QEMU, -icount shift=0: 1 instruction = 1 ns of virtual time. ---
out=$(tests/target/run-qemu.sh --icount --timeout 120 "$bench_elf" | tr -d '\r')
grep -q '^BENCH done' <<<"$out" || { echo "bench-m4 did not finish:"; echo "$out"; exit 1; }
core_hz=$(sed -n 's/^BENCH core_hz=//p' <<<"$out")
# instructions per iteration = cycles / iterations * (1e9 ns/s / core_hz) under icount shift=0
ipi() { awk -v n="$1" -v hz="$core_hz" '$1=="BENCH" && $2==n {
          split($3,c,"="); split($4,i,"="); printf "%.1f", c[2] / i[2] * 1e9 / hz }' <<<"$out"; }
cal=$(ipi calibration_2insn)
ovh=$(ipi overhead)
net() { awk -v a="$1" -v b="$ovh" 'BEGIN { printf "%.1f", a - b }'; }
chain=$(net "$(ipi core_chain)")
onset=$(net "$(ipi onset_tick)")
comp=$(net "$(ipi comp_step)")
comp_plain=$(net "$(ipi comp_step_plain)")
lut=$(net "$(ipi lut_eval)")
demo=$(net "$(ipi demo_tick)")
verdict() { awk -v v="$1" -v t="$2" 'BEGIN { print (v <= t) ? "met" : "NOT met" }'; }

# --- Transition model (table v2, 16 operators; bench/bench_pi.c, report_pi() in bench_m4.c). ---
# Averages net of the reference generator (measured alone); worst = largest single-tick
# window net of the empty window, 1 core cycle = 6 instructions of resolution.
pi_net() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", a - b }'; }
pi_row() { # kind label reference
  local gen genw
  gen=$(ipi "pi_$1_gen"); genw=$(ipi "pi_$1_gen_worst")
  local tick tickw comp compw
  tick=$(pi_net "$(ipi "pi_$1_tick")" "$gen"); tickw=$(pi_net "$(ipi "pi_$1_tick_worst")" "$genw")
  comp=$(pi_net "$(ipi "pi_$1_comp")" "$gen"); compw=$(pi_net "$(ipi "pi_$1_comp_worst")" "$genw")
  printf '| M4 instructions per control tick with the transition (onset_tick + comp_step, 16 operators, smoothing on), %s: average / worst single tick | %s / %s | <= 250 / <= 600 (%s / %s) | bench-m4.elf report_pi(): %s; 100000 ticks; average between two port_cycles() reads net of the reference generator, worst = largest tick timed alone by SysTick with its interrupt off, net of an empty window (resolution 6 instructions) |\n' \
    "$2" "$tick" "$tickw" "$(verdict "$tick" 250)" "$(verdict "$tickw" 600)" "$3"
  printf '| of which comp_step (f^-1, PI^-1 with 16 operators, B/2 offset, ramp), %s: average / worst | %s / %s | | same, comp_step alone |\n' "$2" "$comp" "$compw"
}
pi_jumpw=$(pi_net "$(ipi pi_jump_tick_worst)" "$(ipi pi_jump_gen_worst)")
pi_jumpcw=$(pi_net "$(ipi pi_jump_comp_worst)" "$(ipi pi_jump_gen_worst)")
pi_rows=$(pi_row real "realistic reference" "c* in +-30 deg, a reversal every 5000-10000 ticks (0.25-0.5 s at 20 kHz)"; \
          pi_row stress "stress reference" "a reversal every 512 ticks"; \
          printf '| same, worst single tick when every tick reverses and jumps 12-54 deg (all operators released and re-engaged; no real reference does this) | %s (comp_step %s) | <= 600 (%s) | same worst-tick timing, 100000 such ticks |\n' \
            "$pi_jumpw" "$pi_jumpcw" "$(verdict "$pi_jumpw" 600)")

# --- Desktop, desktop-release core (CMAKE_BUILD_TYPE=Release flags). ---
dr=build/desktop-release
release_flags=$(sed -n 's/^CMAKE_C_FLAGS_RELEASE:STRING=//p' $dr/CMakeCache.txt)
cc_desktop=$(sed -n 's/^CMAKE_C_COMPILER:[A-Z]*=//p' $dr/CMakeCache.txt)
mkdir -p $dr/bench
# shellcheck disable=SC2086
"$cc_desktop" -std=c11 $release_flags -Ibench -Ifirmware/core -Icommon bench/bench_desktop.c bench/bench_tick.c \
  $dr/firmware/core/libps_core.a $dr/libps_common.a -o $dr/bench/bench-desktop
desk=$($dr/bench/bench-desktop 20000000)
desk_tps=$(sed -n 's/.*ticks_per_s=\([0-9]*\).*/\1/p' <<<"$desk")
desk_ns=$(sed -n 's/.*ns_per_tick=\([0-9.]*\).*/\1/p' <<<"$desk")
cpu=$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)

# --- Sizes of the USART image playscope-fw.elf. ---
sec() { arm-none-eabi-size -A "$fw" | awk -v s="$1" '$1==s {print $2}'; }
flash=0
for s in .isr_vector .text .ARM.extab .ARM.exidx .init_array .data; do
  v=$(sec $s); flash=$((flash + ${v:-0}))
done
data=$(sec .data); bss=$(sec .bss)
ram_static=$((data + bss))
stack=$((16#$(arm-none-eabi-nm "$fw" | awk '$3=="__stack_size" {print $1}')))
probe=$dr/bench/size_probe.o
arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -fno-common -Ifirmware/core -Icommon \
  -c bench/size_probe.c -o "$probe"
psize() { echo $((16#$(arm-none-eabi-nm -S "$probe" | awk -v s="$1" '$4==s {print $2}'))); }
derived=$(psize probe_calib_derived); hist=$(psize probe_enc_hist)
calib_sz=$(psize probe_calib_t); onset_sz=$(psize probe_onset_t)
tables=$((derived + hist))
ram_aside=$((ram_static - tables))
kib() { awk -v b="$1" 'BEGIN { printf "%.2f KiB (%d B)", b / 1024, b }'; }

cat <<EOF2
| figure | measured | target | how |
|---|---|---|---|
| M4 instructions per control tick (onset_tick incl. encoder history push + comp_step with smoothing) | $chain | <= 120 ($(verdict "$chain" 120)) | bench-m4.elf under \`qemu-system-arm -M netduinoplus2 -icount shift=0\`; 100000 ticks between two SysTick reads (168 MHz core clock, 1 ns/instruction), loop overhead ($ovh) subtracted; ps_core built by the stm32f405 preset (MinSizeRel, -Os) |
| of which onset_tick (history push, timeout check) | $onset | | same, onset_tick alone |
| of which comp_step, smoothing on (200 mm/s, 20000 mm/s^2) | $comp | | same, comp_step alone (the ramp is idle between reversals) |
| comp_step, no smoothing (eq. 4 as written) | $comp_plain | | same, comp_reset(lim = NULL) |
| one lut_eval (comp_step makes two) | $lut | | same, lut_eval(f_inv) alone |
| demo tick (reference triangle + reversal bookkeeping + chain) | $demo | | same, ctl_loop_tick() of bench/bench_tick.c |
$pi_rows
| instruction-count calibration (subs+bne loop) | $cal per iteration | 2.0 | same timer, a loop of exactly 2 instructions |
| desktop throughput of the chain | $desk_tps ticks/s ($desk_ns ns/tick) | | bench-desktop, same chain, best of 5 x 20e6 ticks, desktop-release flags \`$release_flags\`, $cpu |
| playscope-fw.elf flash | $(kib $flash) | < 24 KiB ($(verdict "$flash" 24576)) | arm-none-eabi-size -A: .isr_vector + .text + .ARM.exidx + .init_array + .data |
| playscope-fw.elf RAM, tables aside | $(kib $ram_aside) static (.data + .bss); $(kib $((ram_aside + stack))) with the stack | < 16 KiB ($(verdict "$((ram_aside + stack))" 16384) with the stack) | .data + .bss minus the tables below; the stack is the linker-script reservation __stack_size |
| tables: calib_t derived buffers (f^-1, z_up, z_down) | $(kib $derived) | | sizeof of the three CALIB_DERIVED_MAX buffers (calib_t total $(kib $calib_sz)) |
| tables: encoder history (enc_hist_t in onset_t) | $(kib $hist) | | sizeof(enc_hist_t), ENC_HIST_LEN samples (onset_t total $(kib $onset_sz)) |
| playscope-fw.elf RAM, everything | $(kib $ram_static) static; $(kib $((ram_static + stack))) with the stack | | .data + .bss, + __stack_size |
EOF2
