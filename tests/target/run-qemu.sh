#!/usr/bin/env bash
# Run one STM32F405 ELF under QEMU (netduinoplus2, Cortex-M4); exit with its semihosting status.
# Usage: tests/target/run-qemu.sh [--timeout SECONDS] [--icount] [--input TEXT] ELF
#   --timeout  kill QEMU after SECONDS (default 120; exit 124 as timeout(1) does)
#   --icount   -icount shift=0: one instruction = 1 ns of virtual time (for the bench)
#   --icount-shift N  -icount shift=N: one instruction = 2^N ns (finer per-call timing)
#   --input    bytes fed to USART1 RX one second after start (the model drops bytes that
#              arrive before the guest enables the USART); default none, stdin /dev/null
set -uo pipefail
timeout_s=120
icount=()
input=""
while [ $# -gt 1 ]; do
  case $1 in
    --timeout) timeout_s=$2; shift 2 ;;
    --icount) icount=(-icount shift=0); shift ;;
    --icount-shift) icount=(-icount "shift=$2"); shift 2 ;;
    --input) input=$2; shift 2 ;;
    *) echo "run-qemu.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
elf=${1:?usage: run-qemu.sh [--timeout S] [--icount] [--input TEXT] ELF}
[ -f "$elf" ] || { echo "run-qemu.sh: no such ELF: $elf" >&2; exit 2; }
# -monitor none: with -nographic the monitor would otherwise share stdio with the UART.
# The exit status is the guest's SYS_EXIT_EXTENDED code (QEMU exits with it).
qemu=(qemu-system-arm -M netduinoplus2 -nographic -monitor none -serial stdio
      -semihosting-config enable=on,target=native "${icount[@]}" -kernel "$elf")
if [ -n "$input" ]; then
  { sleep 1; printf "%s" "$input"; } | timeout --kill-after=5 "$timeout_s" "${qemu[@]}"
  rc=${PIPESTATUS[1]}
else
  timeout --kill-after=5 "$timeout_s" "${qemu[@]}" </dev/null
  rc=$?
fi
[ $rc -eq 124 ] && echo "run-qemu.sh: TIMEOUT after ${timeout_s} s: $elf" >&2
exit $rc
