#!/usr/bin/env bash
# Mutation testing of the core files the pose solver and the fits depend on, with the
# cta-core unit tests: `cargo mutants` changes the code one operator or function body at a
# time and checks that some test fails. Not in CI (hours for all seven files); see
# core/MUTANTS.md for what it found and the mutants listed there as equivalent.
#
#   bash core/mutants.sh                      # mrp collinearity pattern uncertainty emulator glsdc pose
#   bash core/mutants.sh mrp uncertainty      # some of them
#   bash core/mutants.sh mrp -- -F 'shadow'   # extra cargo-mutants arguments after --
#
# Environment: JOBS (default 1: parallel builds need a core each), TIMEOUT (test timeout, s,
# default 60), OUT (default target/mutants: OUT/<file>/mutants.out/{caught,missed,...}.txt).
# Exits non-zero when a missed or timed-out mutant is not in core/MUTANTS.md's list.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

command -v cargo-mutants >/dev/null 2>&1 || cargo install --locked cargo-mutants

files=()
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --) shift; extra=("$@"); break ;;
    *) files+=("${1%.rs}"); shift ;;
  esac
done
[ ${#files[@]} -gt 0 ] || files=(mrp collinearity pattern uncertainty emulator glsdc pose)

# cargo-mutants builds in a copy of the tree: with one job, one target directory for all the
# copies keeps the dependencies built once (the copies' cta-core builds to the same file, so
# with more jobs each copy keeps its own). No debug info: an incremental build of cta-core's
# tests takes 5-8 s instead of 15-35 s (the dependencies are rebuilt once for it).
if [ "${JOBS:-1}" = 1 ]; then
  export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
fi
export CARGO_PROFILE_DEV_DEBUG=0
out="${OUT:-$root/target/mutants}"
listed=$(mktemp)
trap 'rm -f "$listed"' EXIT
# The equivalent mutants of core/MUTANTS.md, without their line and column numbers.
grep -soE '^- `core/src/[a-z0-9_/]+\.rs:[0-9]+:[0-9]+: [^`]+`' core/MUTANTS.md |
  sed -E 's/^- `//; s/`$//; s/:[0-9]+:[0-9]+:/:/' | sort >"$listed" || true

status=0
for f in "${files[@]}"; do
  echo "== core/src/$f.rs"
  mkdir -p "$out/$f"
  # --lib: the unit tests (the integration tests under core/tests would double each build);
  # trig's exhaustive f32 check (5 s) reaches none of these files.
  cargo mutants -p cta-core -f "core/src/$f.rs" --jobs "${JOBS:-1}" --timeout "${TIMEOUT:-60}" \
    -C --lib -o "$out/$f" "${extra[@]}" -- -- --skip trig:: || true
  m="$out/$f/mutants.out"
  n() { cat "$m/$1.txt" 2>/dev/null | grep -c . || true; }
  echo "core/src/$f.rs: $(n caught) caught, $(n missed) missed, $(n unviable) unviable, $(n timeout) timeout"
  unlisted=$(cat "$m/missed.txt" "$m/timeout.txt" 2>/dev/null | sed -E 's/:[0-9]+:[0-9]+:/:/' |
    sort | comm -23 - "$listed")
  if [ -n "$unlisted" ]; then
    echo "not caught and not listed as equivalent in core/MUTANTS.md:"
    echo "$unlisted" | sed 's/^/  /'
    status=1
  fi
done
exit $status
