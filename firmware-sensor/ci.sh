#!/usr/bin/env bash
# Sensor-board firmware checks (called by the root .ci/run as `bash firmware-sensor/ci.sh`):
#
#  1. build the firmware for the STM32F103C8 (thumbv7m-none-eabi) in its own cargo
#     invocation, from this folder (so its .cargo/config.toml profile is the one used by
#     `cargo run --release`), and print flash and static RAM;
#  2. run the QEMU pose program (tests/qemu, Cortex-M3 lm3s6965evb, built at the
#     firmware's opt-level) for the pinhole and the near-field model, the latter also with
#     the spot magnitudes (POSE_MODEL=nearfield-mag: a calibration with a magnitude law):
#     instructions of one warm 10-beacon solve, and of core's 20-beacon four-array
#     constellation (the chip's capacity; `cta sensor accuracy --constellation four-19`, the
#     one that meets every accuracy claim, is it without channel 19, whose frequency is
#     channel 2's), near-field with and without the magnitudes;
#  2b. the same program with POSE_COLD=1: instructions of one cold frame (the target turned
#     90, 180 and -150 deg about the line of sight and tilted 20 deg, solved from nothing:
#     the attitude-independent cold start, then GLSDC), the largest of the three, for the
#     pinhole and the near-field model with 10 beacons and the near-field with 20;
#  3. compare the on-target f32 answer with the host's f64 answer (example pose_reference),
#     for every run of step 2, and the magnitudes each fitted (every beacon's with the law,
#     none without);
#  3b. run the QEMU trig program (untraced, a few seconds): the chip's face-angle sine and
#     cosine (cta_core::trig, fixed point) against libm's sinf/cosf on the target;
#  4. run the QEMU board program: the board's own code (Board::init and Board::poll, as
#     the chip's main calls them) through a session that reaches every deep path (requests,
#     flash writes, the 20-beacon near-field pose with the magnitudes and without), measure
#     its peak stack by painting, and count its warm 20-beacon frames from the NorthStar's
#     bytes to the pose report, with the magnitudes and from the spots alone (reported);
#  5. fail when over budget: flash <= 48 KiB, RAM <= 12 KiB, one warm 10-beacon solve
#     <= 1,000,000 instructions, for each model (the issue's budget), and the warm
#     20-beacon near-field solve from the spots under the same line (ours: so that four-19
#     stays an option). The warm solves with the magnitudes are reported against it, not
#     held to it (see step 5 below and firmware-sensor/README.md, "Budgets"). A cold frame
#     (step 2b) <= 7,200,000 instructions: one 10 Hz frame at 72 MHz, taking instructions
#     for cycles (a proxy: the Cortex-M3 takes more than one cycle for loads, branches and
#     the soft-float library's multiplies, and flash wait states add more at 72 MHz).
#
# RAM = static (.data + .bss + .uninit of the firmware: the board's state is a static)
#     + the chip main's own frame (from the firmware's disassembly: its prologue)
#     + the board's peak stack below main (QEMU, step 4)
#     + ENTRY_IRQ_ALLOWANCE: the reset handler's frame and one USART interrupt on top
#       (the 32-byte exception frame, the handler's 8 saved registers, its small callees).
#
# CTA_SENSOR_BUDGETS=report prints the same figures and verdicts but exits 0 on budget
# overruns (build, QEMU or f32/f64 mismatches still fail).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
mode=${CTA_SENSOR_BUDGETS:-enforce}
FLASH_BUDGET=$((48 * 1024))
RAM_BUDGET=$((12 * 1024))
INSN_BUDGET=1000000
# One 10 Hz frame at 72 MHz, in instructions (a proxy for cycles; see step 5).
COLD_BUDGET=7200000
ENTRY_IRQ_ALLOWANCE=256
over=0

rustup target add thumbv7m-none-eabi >/dev/null 2>&1 || true
rustup component add llvm-tools >/dev/null 2>&1 || true
host=$(rustc -vV | sed -n 's/^host: //p')
size_tool="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
[ -x "$size_tool" ] || size_tool=$(command -v llvm-size || true)
[ -n "$size_tool" ] || { echo "ci.sh: llvm-size not found (rustup component add llvm-tools)" >&2; exit 1; }

echo "== firmware-sensor: build for thumbv7m-none-eabi (STM32F103C8)"
(cd "$here" && cargo build --release --target thumbv7m-none-eabi -p cta-firmware-sensor)
target_dir=${CARGO_TARGET_DIR:-$root/target}
elf="$target_dir/thumbv7m-none-eabi/release/cta-firmware-sensor"
sec() { "$size_tool" -A "$elf" | awk -v s="$1" '$1 == s { print $2 }'; }
n() { local v; v=$(sec "$1"); echo "${v:-0}"; }
flash=$(( $(n .vector_table) + $(n .text) + $(n .rodata) + $(n .data) ))
ram_static=$(( $(n .data) + $(n .bss) + $(n .uninit) ))

echo "== QEMU pose benchmark (Cortex-M3, lm3s6965evb)"
# Runs: MODEL for 10 beacons, MODEL20 for 20 (POSE_BEACONS=20).
runs=(pinhole nearfield nearfield-mag nearfield20 nearfield-mag20)
declare -A insn stack f32line
for run in "${runs[@]}"; do
  model=${run%20}
  out=$(POSE_MODEL=$model POSE_BEACONS=${run#"$model"} POSE_MAG_SCALE= bash "$root/tests/qemu/run.sh" pose)
  echo "$out"
  insn[$run]=$(echo "$out" | sed -n 's/^pose: .* mean=\([0-9.]*\) max=\([0-9]*\).*/\2/p')
  stack[$run]=$(echo "$out" | sed -n 's/^STACK solve_peak_bytes=\([0-9]*\).*/\1/p')
  f32line[$run]=$(echo "$out" | grep '^POSE f32')
  [ -n "${insn[$run]}" ] && [ -n "${stack[$run]}" ] && [ -n "${f32line[$run]}" ] \
    || { echo "ci.sh: QEMU pose run ($run) printed no count" >&2; exit 1; }
done

echo "== QEMU cold frames (attitude-independent cold start, then GLSDC)"
cold_runs=(pinhole nearfield nearfield20)
declare -A cold_insn
for run in "${cold_runs[@]}"; do
  model=${run%20}
  out=$(POSE_COLD=1 POSE_MODEL=$model POSE_BEACONS=${run#"$model"} POSE_MAG_SCALE= bash "$root/tests/qemu/run.sh" pose)
  echo "$out"
  cold_insn[$run]=$(echo "$out" | sed -n 's/^pose: .* mean=\([0-9.]*\) max=\([0-9]*\).*/\2/p')
  [ -n "${cold_insn[$run]}" ] && echo "$out" | grep -q '^COLD f32 ' \
    || { echo "ci.sh: QEMU cold run ($run) printed no count" >&2; exit 1; }
done

echo "== f32 on target vs f64 on the host"
(cd "$root" && cargo build --quiet -p cta-firmware-sensor --example pose_reference)
for run in "${runs[@]}"; do
  model=${run%20}
  ref=$(cd "$root" && cargo run --quiet -p cta-firmware-sensor --example pose_reference -- "$model" ${run#"$model"} | grep '^POSE f64')
  echo "target: ${f32line[$run]}"
  echo "host:   $ref"
  # The magnitudes fitted: the same on both sides, every beacon's with the law, none without.
  counts() { echo "$1" | sed -n 's/.* beacons=\([0-9]*\) magnitudes=\([0-9]*\) .*/\1 \2/p'; }
  read -r nb nm <<<"$(counts "${f32line[$run]}")"
  [ -n "$nm" ] && [ "$(counts "$ref")" = "$nb $nm" ] && [ "$nm" = "$(case $model in *-mag) echo "$nb";; *) echo 0;; esac)" ] \
    || { echo "ci.sh: magnitudes fitted ($run): target \"$(counts "${f32line[$run]}")\", host \"$(counts "$ref")\" (beacons, magnitudes)" >&2; exit 1; }
  # Position within 1e-3 in and MRP within 1e-4 (0.03 deg): far below the noise floor.
  # Both lines must read "... t= x y z q= a b c" with six numbers (awk would take a
  # missing or non-numeric field, NaN included, for 0 and pass).
  printf '%s\n%s\n' "${f32line[$run]}" "$ref" | awk '
    { for (i = 1; i <= NF; i++) if ($i == "t=" && $(i + 4) == "q=") { ok[NR] = 1; for (k = 0; k < 3; k++) t[NR, k] = $(i + 1 + k); for (k = 0; k < 3; k++) q[NR, k] = $(i + 5 + k) } }
    END {
      if (NR != 2) { printf "  expected two POSE lines, got %d\n", NR; exit 1 }
      for (l = 1; l <= 2; l++) {
        if (!ok[l]) { printf "  POSE line %d has no \"t= x y z q= a b c\"\n", l; exit 1 }
        for (k = 0; k < 3; k++) if (t[l, k] !~ /^[-+]?([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][-+]?[0-9]+)?$/ || q[l, k] !~ /^[-+]?([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][-+]?[0-9]+)?$/) { printf "  POSE line %d: a field of t= or q= is not a number\n", l; exit 1 }
      }
      dt = 0; dq = 0
      for (k = 0; k < 3; k++) { a = t[1, k] - t[2, k]; if (a < 0) a = -a; if (a > dt) dt = a; b = q[1, k] - q[2, k]; if (b < 0) b = -b; if (b > dq) dq = b }
      printf "  max |dt| = %.2e in, max |dq| = %.2e\n", dt, dq
      exit !(dt <= 1e-3 && dq <= 1e-4)
    }' || { echo "ci.sh: f32 answer ($run) does not match the host f64 answer" >&2; exit 1; }
done

echo "== face-angle sine and cosine on the target vs libm (QEMU)"
(cd "$root/tests/qemu" && cargo build --release --quiet --bin trig \
  --config 'profile.release.package.cta-qemu.opt-level="z"' \
  --config 'profile.release.package."*".opt-level="z"' \
  --config 'profile.release.package.cta-core.opt-level=3')
trig_elf="${CARGO_TARGET_DIR:-$root/tests/qemu/target}/thumbv7m-none-eabi/release/trig"
out=$(qemu-system-arm -machine lm3s6965evb -cpu cortex-m3 -nographic \
  -semihosting-config enable=on,target=native -kernel "$trig_elf" 2>/dev/null) || true
echo "$out"
echo "$out" | grep -q '^TRIG checked=[1-9][0-9]* mismatches=0$' \
  || { echo "ci.sh: the target's face-angle sine/cosine differ from libm's" >&2; exit 1; }

echo "== QEMU board session (the board's code below main: init, requests, 20-beacon poses with magnitudes)"
out=$(bash "$root/tests/qemu/run.sh" board)
echo "$out"
peak=$(echo "$out" | sed -n 's/^STACK board_peak_bytes=\([0-9]*\).*/\1/p')
[ -n "$peak" ] || { echo "ci.sh: QEMU board run printed no stack figure" >&2; exit 1; }
# Warm 20-beacon frames through the board: segments 1-3 with the magnitudes, 4-5 from the
# spots alone (tests/qemu/src/bin/board.rs).
counts=$(echo "$out" | sed -n 's/^board: counts=\([0-9,]*\)$/\1/p')
read -r frame_mag frame_spots < <(echo "$counts" | awk -F, 'NF == 5 {
  a = $1; for (i = 2; i <= 3; i++) if ($i > a) a = $i; b = ($4 > $5) ? $4 : $5; print a, b }')
[ -n "${frame_spots:-}" ] || { echo "ci.sh: QEMU board run printed no frame counts (\"$counts\")" >&2; exit 1; }
# The chip main's own frame: its prologue's pushed registers and stack adjustment.
main_frame=$(bash "$root/tests/qemu/main_frame.sh" "$elf")
ram=$(( ram_static + main_frame + peak + ENTRY_IRQ_ALLOWANCE ))
verdict() { if [ "$1" -le "$2" ]; then echo "ok"; else echo "OVER BUDGET"; fi; }
check() { [ "$1" -le "$2" ] || over=1; }
check "$flash" "$FLASH_BUDGET"; check "$ram" "$RAM_BUDGET"
# The instruction budget holds for both models: the pinhole (calibrated eq 65) and the
# near-field (eq 60-63) solve from the spots, for 10 beacons and (ours) 20; see
# firmware-sensor/README.md, "Budgets". The 10-beacon solve with the magnitudes is held to
# it too (the carried linearisation keeps its magnitudes' weights: one Jacobian pass, as
# from the spots); the 20-beacon one with the magnitudes cannot meet it (its 59 rows do not
# fit the 40 the solver carries) and is reported only.
enforced=(pinhole nearfield nearfield-mag nearfield20)
for run in "${enforced[@]}"; do
  check "${insn[$run]}" "$INSN_BUDGET"
done
for run in "${cold_runs[@]}"; do
  check "${cold_insn[$run]}" "$COLD_BUDGET"
done
held() { local r; for r in "${enforced[@]}"; do [ "$r" = "$1" ] && return 0; done; return 1; }
# The verdict of an instruction count: held to the budget, or only reported against it.
insn_verdict() {
  if held "$1"; then verdict "${insn[$1]}" "$INSN_BUDGET"
  elif [ "${insn[$1]}" -le "$INSN_BUDGET" ]; then echo "under it (reported, not enforced)"
  else echo "OVER it (reported, not enforced)"; fi
}
echo "== firmware-sensor figures"
printf 'flash                        %6d B (%.1f KiB) / %d B: %s, %d B left\n' "$flash" "$(awk -v f="$flash" 'BEGIN { print f / 1024 }')" "$FLASH_BUDGET" "$(verdict "$flash" "$FLASH_BUDGET")" "$(( FLASH_BUDGET - flash ))"
printf 'RAM static                   %6d B\n' "$ram_static"
printf 'RAM stack: main frame        %6d B\n' "$main_frame"
printf 'RAM stack: board below main  %6d B (QEMU: solve-only peak %d B, 20 beacons; %d B with the magnitudes)\n' "$peak" "${stack[nearfield20]}" "${stack[nearfield-mag20]}"
printf 'RAM stack: entry, interrupt  %6d B (allowance)\n' "$ENTRY_IRQ_ALLOWANCE"
printf 'RAM total                    %6d B / %d B: %s, %d B left\n' "$ram" "$RAM_BUDGET" "$(verdict "$ram" "$RAM_BUDGET")" "$(( RAM_BUDGET - ram ))"
hz() { awk -v n="$1" 'BEGIN { printf "%.0f", 72e6 / n }'; }
for run in "${runs[@]}"; do
  model=${run%20}
  beacons=10; [ "$run" = "$model" ] || beacons=20
  printf 'warm %d-beacon solve, %-13s %8d instructions / %d (%s Hz at 72 MHz): %s\n' "$beacons" "$model" "${insn[$run]}" "$INSN_BUDGET" "$(hz "${insn[$run]}")" "$(insn_verdict "$run")"
done
for run in "${cold_runs[@]}"; do
  model=${run%20}
  beacons=10; [ "$run" = "$model" ] || beacons=20
  printf 'cold %d-beacon frame, %-13s %8d instructions / %d (one 10 Hz frame at 72 MHz, instructions for cycles): %s\n' "$beacons" "$model" "${cold_insn[$run]}" "$COLD_BUDGET" "$(verdict "${cold_insn[$run]}" "$COLD_BUDGET")"
done
printf 'warm 20-beacon frame through the board (NorthStar bytes to pose report): %d instructions with the magnitudes, %d from the spots alone (reported)\n' "$frame_mag" "$frame_spots"
if [ "$over" -ne 0 ]; then
  if [ "$mode" = report ]; then
    echo "firmware-sensor: OVER BUDGET (CTA_SENSOR_BUDGETS=report: not failing)"
  else
    echo "firmware-sensor: OVER BUDGET" >&2
    exit 1
  fi
fi
echo "firmware-sensor: done"
