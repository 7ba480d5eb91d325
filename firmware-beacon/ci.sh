#!/usr/bin/env bash
# CI for the beacon board (called by the root .ci/run as `bash firmware-beacon/ci.sh`):
#  1. build the firmware for thumbv7m-none-eabi in its own cargo invocation;
#  2. count the instructions of the modulator tick under QEMU (Cortex-M3) with all 100
#     LEDs modulated, and print the interrupt load at 72 MHz; fail above 25 %; check the
#     tick cost model the board uses to refuse overloads against the counts (three cases);
#  3. run the QEMU board program (the board's own code, as the chip's main calls it,
#     through every request), measure its peak stack by painting, and print the most
#     instructions one received byte holds the main loop for;
#  4. print flash and RAM use and fail if over the root memory.x budget.
#
# RAM = static (.data + .bss + .uninit: the board and the modulator are statics)
#     + the chip main's own frame (from the firmware's disassembly: its prologue)
#     + the board's peak stack below main (QEMU, step 3)
#     + the tick interrupt's stack (QEMU, step 2) and its 32-byte exception frame: the
#       tick has the highest priority and can land on top of everything else
#     + ENTRY_IRQ_ALLOWANCE: the reset handler's frame and the USART interrupt (its
#       exception frame, saved registers and small callees).
# Needs rustup, and qemu-system-arm for steps 2-3 (installed by .ci/run).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
rustup target add thumbv7m-none-eabi >/dev/null
rustup component add llvm-tools >/dev/null
bin_dir="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin"
target_dir=${CARGO_TARGET_DIR:-$root/target}
ENTRY_IRQ_ALLOWANCE=256

echo "== firmware-beacon: build (thumbv7m-none-eabi, release)"
cargo build --release --target thumbv7m-none-eabi -p cta-firmware-beacon
elf="$target_dir/thumbv7m-none-eabi/release/cta-firmware-beacon"

# Budget: the FLASH and RAM lengths of the root memory.x (e.g. "LENGTH = 64K").
len() {
  sed -n "s/^ *$1 *:.*LENGTH *= *\([0-9]*\)\([KM]\?\).*/\1 \2/p" memory.x |
    awk '{ m = ($2 == "K") ? 1024 : ($2 == "M") ? 1048576 : 1; print $1 * m }'
}
flash_budget=$(len FLASH)
ram_budget=$(len RAM)
# Section sizes (sysv format: name size addr). Flash holds the vector table, code,
# read-only data and the initial values of .data; RAM holds .data, .bss and .uninit.
read -r flash ram < <("$bin_dir/llvm-size" -A "$elf" | awk '
  $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { f += $2 }
  $1 == ".data" { f += $2; r += $2 }
  $1 == ".bss" || $1 == ".uninit" { r += $2 }
  END { print f, r }')
echo "== firmware-beacon: tick cost under QEMU (all 100 LEDs modulated)"
tick_hz=$(sed -n 's/^pub const TICK_HZ: u32 = \([0-9_]*\);.*/\1/p' core/src/schedule.rs | tr -d _)
# (Not `tee /dev/stderr`: when stderr is a log file, tee would truncate it.)
out=$(CARGO_TARGET_DIR="$target_dir/qemu" bash tests/qemu/run.sh beacon_tick)
echo "$out"
line=$(echo "$out" | grep '^beacon_tick: segments=')
mean=$(echo "$line" | sed 's/.*mean=\([0-9.]*\).*/\1/')
max=$(echo "$line" | sed 's/.*max=\([0-9]*\).*/\1/')
echo "$mean $max $tick_hz" | awk '{
  load = 100 * $1 * $3 / 72e6
  printf "beacon tick: %.1f instructions per tick on average (max %d) at %d Hz: interrupt load %.1f %% of 72 MHz (target <= 25 %%)\n", $1, $2, $3, load
  if (load > 25) { print "beacon tick: interrupt load over 25 %" > "/dev/stderr"; exit 1 }
}'
tick_stack=$(echo "$out" | sed -n 's/^STACK tick_peak_bytes=\([0-9]*\).*/\1/p')
[ -n "$tick_stack" ] || { echo "ci.sh: QEMU tick run printed no stack figure" >&2; exit 1; }

# The board refuses settings whose tick cost, by the model of cta_core::schedule::tick_cost,
# is over its budget: the model must not be below the measured cost. Checked on the case
# above, on the accepted mixture nearest the budget (10 LEDs at all 20 frequencies, 90 at
# one) and on the case where the model is tightest (every LED at the same two frequencies).
echo "== firmware-beacon: tick cost model against QEMU"
check_model() {
  local out=$1 case_line model_mean measured
  case_line=$(echo "$out" | grep '^TICK case=')
  model_mean=$(echo "$case_line" | sed 's/.*model_mean=\([0-9]*\).*/\1/')
  measured=$(echo "$out" | grep '^beacon_tick: segments=' | sed 's/.*mean=\([0-9.]*\).*/\1/')
  [ -n "$model_mean" ] && [ -n "$measured" ] || { echo "ci.sh: no tick model figures" >&2; exit 1; }
  echo "$case_line $measured" | awk '{
    split($2, c, "="); split($3, m, "=");
    printf "tick model, %-8s: %d instructions per tick, measured %.1f: %s\n", c[2], m[2], $NF, ($NF <= m[2] ? "ok" : "MODEL BELOW MEASURED")
    if ($NF > m[2]) exit 1
  }' || { echo "ci.sh: the tick cost model is below the measured cost" >&2; exit 1; }
}
check_model "$out"
for case in mixed10 same100; do
  check_model "$(BEACON_TICK_CASE=$case CARGO_TARGET_DIR="$target_dir/qemu" bash tests/qemu/run.sh beacon_tick)"
done

echo "== firmware-beacon: board session under QEMU (the board's code below main)"
out=$(CARGO_TARGET_DIR="$target_dir/qemu" bash tests/qemu/run.sh beacon_board)
echo "$out"
peak=$(echo "$out" | sed -n 's/^STACK beacon_board_peak_bytes=\([0-9]*\).*/\1/p')
[ -n "$peak" ] || { echo "ci.sh: QEMU board run printed no stack figure" >&2; exit 1; }
# The costliest received byte of the session (the one that completes the largest request):
# how long the main loop is held at most.
byte_max=$(echo "$out" | sed -n 's/^beacon_board: segments=.* max=\([0-9]*\).*/\1/p')
[ -n "$byte_max" ] || { echo "ci.sh: QEMU board run printed no instruction count" >&2; exit 1; }
main_frame=$(bash tests/qemu/main_frame.sh "$elf")
ram_total=$(( ram + main_frame + peak + tick_stack + 32 + ENTRY_IRQ_ALLOWANCE ))

echo "== firmware-beacon figures"
printf 'firmware-beacon flash: %d bytes of %d (%.1f %%), %d B left\n' "$flash" "$flash_budget" "$(echo "$flash $flash_budget" | awk '{print 100*$1/$2}')" "$(( flash_budget - flash ))"
printf 'RAM static                   %6d B\n' "$ram"
printf 'RAM stack: main frame        %6d B\n' "$main_frame"
printf 'RAM stack: board below main  %6d B (QEMU)\n' "$peak"
printf 'RAM stack: tick interrupt    %6d B (QEMU, + 32 B exception frame)\n' "$tick_stack"
printf 'RAM stack: entry, USART      %6d B (allowance)\n' "$ENTRY_IRQ_ALLOWANCE"
printf 'firmware-beacon RAM: %d bytes of %d (%.1f %%), %d B left\n' "$ram_total" "$ram_budget" "$(echo "$ram_total $ram_budget" | awk '{print 100*$1/$2}')" "$(( ram_budget - ram_total ))"
printf 'main loop held at most %d instructions by one received byte (%.2f ms at 72 MHz, one per cycle)\n' "$byte_max" "$(awk -v n="$byte_max" 'BEGIN { print n / 72e3 }')"
if [ "$flash" -gt "$flash_budget" ] || [ "$ram_total" -gt "$ram_budget" ]; then
  echo "firmware-beacon: over the memory.x budget" >&2
  exit 1
fi
