#!/usr/bin/env bash
# run.sh [EXECS [TARGET...]]
# Builds every fuzz target and runs each (or the TARGETs named), one after another, for EXECS
# executions (default ten million; libFuzzer's -runs=), single job, under nice -n 10, from
# corpus/<target>/ (seeded by seed.sh when missing). Prints per target the executions, seconds,
# executions per second and crashes (inputs saved under artifacts/<target>/, the run's output in
# logs/<target>.log). Exits non-zero when a target crashed, hung (-timeout=10 s per input) or
# stopped short of EXECS.
#
# Rust targets: cargo-fuzz (libFuzzer) on the installed stable toolchain with RUSTC_BOOTSTRAP=1,
# release with debug assertions and overflow checks, no sanitizer (the fuzzed code has no
# unsafe). virtual_akd is built without trace-compares instrumentation: with it, building the
# drives' object dictionary at each power cycle takes most of the time (4x fewer executions).
# The pcapng reader is Python: atheris (libFuzzer's engine) in a venv of its own, .venv/.
set -euo pipefail
execs=${1:-10000000}
shift || true
here=$(cd "$(dirname "$0")" && pwd)
cd "$here"
export RUSTC_BOOTSTRAP=1
[ -d corpus ] || bash seed.sh
mkdir -p logs

rust_targets=(frame mailbox coe sii eoe_foe virtual_akd)
if [ $# -gt 0 ]; then targets=("$@"); else targets=("${rust_targets[@]}" pcapng_reader); fi
nice -n 10 cargo fuzz build -O -a -s none >logs/build.log 2>&1 || { cat logs/build.log; exit 1; }
nice -n 10 cargo fuzz build -O -a -s none --no-trace-compares --target-dir target/no-trace-compares virtual_akd \
  >>logs/build.log 2>&1 || { cat logs/build.log; exit 1; }
if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import atheris' 2>/dev/null; then
  python3 -m venv .venv && .venv/bin/pip install -q atheris
fi

command_of() {
  case $1 in
    virtual_akd) echo "target/no-trace-compares/x86_64-unknown-linux-gnu/release/virtual_akd -max_len=4096" ;;
    pcapng_reader) echo ".venv/bin/python fuzz_targets/pcapng_reader.py -max_len=4096" ;;
    *) echo "target/x86_64-unknown-linux-gnu/release/$1" ;;
  esac
}

failed=0
printf '%-14s %12s %9s %10s %8s\n' target executions seconds exec/s crashes
for target in "${targets[@]}"; do
  mkdir -p "corpus/$target" "artifacts/$target"
  before=$(find "artifacts/$target" -type f | wc -l)
  start=$(date +%s.%N)
  # shellcheck disable=SC2046
  nice -n 10 $(command_of "$target") -runs="$execs" -timeout=10 -print_final_stats=1 \
    -artifact_prefix="artifacts/$target/" "corpus/$target" >"logs/$target.log" 2>&1 || true
  seconds=$(echo "$(date +%s.%N) - $start" | bc)
  done_runs=$(grep -oP '^stat::number_of_executed_units:\s*\K[0-9]+' "logs/$target.log" | tail -1 || true)
  crashes=$(($(find "artifacts/$target" -type f | wc -l) - before))
  [ "$crashes" -eq 0 ] && [ "${done_runs:-0}" -ge "$execs" ] || failed=1
  printf '%-14s %12s %9.1f %10.0f %8s\n' "$target" "${done_runs:-?}" "$seconds" \
    "$(echo "${done_runs:-0} / $seconds" | bc -l)" "$crashes"
done
exit $failed
