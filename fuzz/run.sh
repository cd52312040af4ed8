#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# fuzz/run.sh BUILD SECONDS [TARGET...]: runs each libFuzzer target BUILD/fuzz_<target> (every
# fuzz/*.cpp when none is named) for SECONDS from fuzz/corpus/<target>/, then prints per target the
# executions, executions per second, new inputs and crashes. `make fuzz` calls it.
#
# New inputs go to BUILD/fuzz/<target>/corpus (libFuzzer writes into its first corpus folder),
# crash reproducers to BUILD/fuzz/<target>/artifacts/; the repository's corpus is only read,
# unless FUZZ_MERGE=1, which merges the new inputs that add coverage into fuzz/corpus/<target>/.
# A crashing target stops at its first crash (the reproducer is named in the table); save it as
# fuzz/regressions/<target>/<name> once fixed, and `make test` replays it from then on.
# Extra libFuzzer flags: FUZZ_FLAGS="-max_len=100000"; FUZZ_JOBS=2 runs two targets at a time.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$(cd "$1" && pwd)"
seconds="$2"
shift 2
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for f in "$root"/fuzz/*.cpp; do targets+=("$(basename "$f" .cpp)"); done
fi

# Halt on the first report, with stacks; leaks are reported too.
export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:symbolize=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$root/fuzz/lsan.supp:print_suppressions=0}"

# One target: runs it, then writes its line of the table to BUILD/fuzz/<target>/summary.txt.
run_one() {
  local t="$1" program="$build/fuzz_$1" work="$build/fuzz/$1" seeds="$root/fuzz/corpus/$1"
  mkdir -p "$work/corpus" "$work/artifacts" "$seeds"
  local log="$work/log.txt"
  echo "fuzz: $t for ${seconds}s (log: $log)"
  local start
  start=$(date +%s)
  # shellcheck disable=SC2086
  nice -n 10 "$program" -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=2048 \
    -timeout=10 -print_final_stats=1 -artifact_prefix="$work/artifacts/" ${FUZZ_FLAGS:-} \
    "$work/corpus" "$seeds" > "$log" 2>&1
  local status=$?
  local elapsed=$(( $(date +%s) - start ))
  local execs rate added crash kind
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  added=$(sed -n 's/^stat::new_units_added: *//p' "$log" | tail -1)
  crash=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
  if [ $status -ne 0 ]; then
    kind=$(grep -a -m1 -oE 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer): [a-z-]+|runtime error|deadly signal|out-of-memory|timeout' "$log" || true)
    printf '%-16s %6ss %12s %8s %6s  CRASH %s: %s\n' "$t" "$elapsed" "${execs:-?}" "${rate:-?}" \
      "${added:-?}" "${kind:-exit $status}" "${crash:-see log}" > "$work/summary.txt"
  else
    printf '%-16s %6ss %12s %8s %6s  0 crashes\n' "$t" "$elapsed" "${execs:-?}" "${rate:-?}" \
      "${added:-?}" > "$work/summary.txt"
  fi
  if [ "${FUZZ_MERGE:-}" = 1 ]; then
    "$program" -merge=1 "$seeds" "$work/corpus" > "$work/merge.txt" 2>&1 || true
  fi
}

for t in "${targets[@]}"; do
  if [ ! -x "$build/fuzz_$t" ]; then
    echo "fuzz: $build/fuzz_$t is missing (cmake --build $build --target fuzzers)" >&2
    exit 2
  fi
  rm -f "$build/fuzz/$t/summary.txt"
done
# FUZZ_JOBS targets at a time (default 1: each target has a core to itself on a 2-core machine
# that also builds).
jobs_max="${FUZZ_JOBS:-1}"
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n; done
  run_one "$t" &
done
wait

failed=0
echo
printf '%-16s %7s %12s %8s %6s  %s\n' target time executions exec/s new result
for t in "${targets[@]}"; do
  cat "$build/fuzz/$t/summary.txt"
  grep -q CRASH "$build/fuzz/$t/summary.txt" && failed=1
done
exit $failed
