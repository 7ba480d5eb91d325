#!/usr/bin/env bash
# Print the stack frame of a firmware's `main` (cortex-m-rt's `__cortex_m_rt_main`), in
# bytes, from its disassembly: the registers its prologue pushes plus its stack
# adjustments before the first branch.
#
#   usage: tests/qemu/main_frame.sh ELF
#
# Both firmware ci.sh scripts add it to their RAM figure: the QEMU programs measure the
# stack below `main` (the boards' work), not `main`'s own frame.
set -euo pipefail
elf=${1:?usage: main_frame.sh ELF}
bin_dir="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin"
# (No early exit in these awk programs: the writer would die of SIGPIPE under pipefail.)
main_sym=$("$bin_dir/llvm-nm" "$elf" | awk '/__cortex_m_rt_main[0-9a-zA-Z_$]*$/ && $2 ~ /[tT]/ && !s { s = $3 } END { print s }')
[ -n "$main_sym" ] || { echo "main_frame.sh: no main in $elf" >&2; exit 1; }
frame=$("$bin_dir/llvm-objdump" -d --no-show-raw-insn --disassemble-symbols="$main_sym" "$elf" | awk '
  function num(v) { gsub("#", "", v); if (v ~ /^0x/) { n = 0; v = tolower(substr(v, 3)); for (i = 1; i <= length(v); i++) n = n * 16 + index("0123456789abcdef", substr(v, i, 1)) - 1; return n } return v + 0 }
  # The prologue: the first instructions, before any branch.
  /\tb/ { done = 1 }
  !done && /\t(push|push\.w|stmdb)\t/ { r = $0; gsub(/[^,{]/, "", r); b += 4 * length(r) }
  !done && /\tsub(\.w|w)?\tsp, (sp, )?#/ { b += num($NF) }
  END { print b + 0 }')
[ "$frame" -gt 0 ] || { echo "main_frame.sh: could not read the frame of $main_sym" >&2; exit 1; }
echo "$frame"
