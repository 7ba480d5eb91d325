#!/usr/bin/env bash
# Build one measurement program of this harness, run it under QEMU (lm3s6965evb,
# Cortex-M3) one instruction per translation block with an execution trace, and
# print the number of instructions executed per segment: from each call of
# `qemu_mark` to the next (the last one ends at `qemu_done`).
#
#   usage: tests/qemu/run.sh BIN        e.g. tests/qemu/run.sh beacon_tick
#
# The environment reaches the program's build: `pose` reads POSE_MODEL (pinhole, nearfield,
# the default, or nearfield-mag: the near-field solve with the spot magnitudes) and
# POSE_BEACONS (20: the 20-beacon constellation) and POSE_MAG_SCALE (a diagnostic: the
# frames' magnitudes multiplied by it), e.g.
#   POSE_MODEL=nearfield-mag POSE_BEACONS=20 tests/qemu/run.sh pose
#
# Output: the program's own output, then a line
#   BIN: segments=N overhead=O mean=M max=X min=Y (instructions per segment, marker overhead subtracted)
# where the overhead O (instructions of an empty segment: the first segments of every
# program are empty on purpose) has been subtracted from mean/max/min; with 16 segments or
# fewer, also a line
#   BIN: counts=C1,C2,... (each segment's, in order, overhead subtracted)
# Needs qemu-system-arm, the thumbv7m-none-eabi target and llvm-tools (installed here
# if missing). Set CARGO_TARGET_DIR to share a target dir.
set -euo pipefail
bin=${1:?usage: run.sh BIN}
here=$(cd "$(dirname "$0")" && pwd)
cd "$here"
rustup target add thumbv7m-none-eabi >/dev/null 2>&1 || true
rustup component add llvm-tools >/dev/null 2>&1 || true
command -v qemu-system-arm >/dev/null || { echo "run.sh: qemu-system-arm not found" >&2; exit 1; }
# Each program built as the firmware whose code it measures (with fat LTO the final
# crate's level governs everything inlined into it, but not the dependencies' own code:
# libm, nalgebra, postcard, heapless): the sensor firmware is built for size, "z" with its
# dependencies at "z" and cta-core at 3 (firmware-sensor/.cargo/config.toml); the beacon
# firmware at "s" with its dependencies at the release default (root Cargo.toml).
case $bin in
  pose|board|trig) profile=(--config 'profile.release.package.cta-qemu.opt-level="z"'
                       --config 'profile.release.package."*".opt-level="z"'
                       --config 'profile.release.package.cta-core.opt-level=3') ;;
  *) profile=(--config 'profile.release.package.cta-qemu.opt-level="s"') ;;
esac
cargo build --release --quiet --bin "$bin" "${profile[@]}"
target_dir=${CARGO_TARGET_DIR:-$here/target}
elf="$target_dir/thumbv7m-none-eabi/release/$bin"
nm="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-nm"
addr() { "$nm" "$elf" | awk -v s="$1" '$3 == s { print $1 }'; }
mark=$(addr qemu_mark)
done_=$(addr qemu_done)
[ -n "$mark" ] && [ -n "$done_" ] && [ "$mark" != "$done_" ] || { echo "run.sh: markers not found in $elf" >&2; exit 1; }
# Trace lines look like: "Trace 0: 0x7f... [00800400/00000d94/00000110/ff000201] symbol";
# the second field in brackets is the guest PC.
fifo=$(mktemp -u); mkfifo "$fifo"; trap 'rm -f "$fifo"' EXIT
awk -v mark="$mark" -v done_="$done_" -v bin="$bin" '
  function close_seg() { if (open) { segs[++n] = count } }
  /^Trace/ {
    split($0, a, "["); split(a[2], f, "/"); pc = f[2]
    if (open) count++
    # As strings: an address such as 0000e360 would compare as the number 0e360 = 0.
    if (pc "" == mark "") { close_seg(); open = 1; count = 0 }
    else if (pc "" == done_ "") { close_seg(); open = 0 }
    next
  }
  END {
    if (n == 0) { print bin ": no segments found" > "/dev/stderr"; exit 1 }
    # Empty leading segments give the marker + loop overhead: the smallest segment.
    ovh = segs[1]; for (i = 1; i <= n; i++) if (segs[i] < ovh) ovh = segs[i]
    sum = 0; mx = 0; mn = -1; m = 0
    for (i = 1; i <= n; i++) { if (i <= 4) continue; v = segs[i] - ovh; sum += v; m++; if (v > mx) mx = v; if (mn < 0 || v < mn) mn = v }
    printf "%s: segments=%d overhead=%d mean=%.1f max=%d min=%d\n", bin, m, ovh, sum / m, mx, mn
    if (m <= 16) { list = ""; for (i = 5; i <= n; i++) list = list (i > 5 ? "," : "") (segs[i] - ovh); print bin ": counts=" list }
  }' "$fifo" &
awk_pid=$!
qemu-system-arm -machine lm3s6965evb -cpu cortex-m3 -nographic \
  -semihosting-config enable=on,target=native -singlestep -d exec,nochain -D "$fifo" \
  -kernel "$elf" 2>/dev/null
wait "$awk_pid"
