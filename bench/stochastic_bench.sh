#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Evaluation and sampling throughput before and after issue 20 (docs/benchmarks.md, "Stochastic
# filtering"): `btf bench` of the same packages by two builds of `btf`, alternated, best of
# ROUNDS rounds of --repeat 5 each (the machine is shared: the best run is the least disturbed).
#
#   bash bench/stochastic_bench.sh OLD_BTF NEW_BTF DIR [ROUNDS]
#
# DIR holds fmf.btfpkg (fmf C = 32, rgb, power-iterations=0), w.btf (UBO2014 DFMF K = 32 half,
# colour model 0) and mlvq.btfpkg (mlvq defaults) of `btf synth --preset woven_fabric --size 256`
# (docs/benchmarks.md, "btf bench", has the commands). OLD_BTF is a build of the commit before
# the work (bd53975), which has neither --filter nor eval-sample: its figures are deterministic.
set -euo pipefail
old=$1; new=$2; dir=$3; rounds=${4:-3}
queries=1048576
rate() {  # rate BIN ARGS... -> M/s, best of the run's repeats
  "$@" --queries $queries --repeat 5 | sed -E 's/.*: [a-z-]+ ([0-9.]+) M\/s.*/\1/'
}
declare -A best
measure() {  # measure KEY BIN ARGS...
  local key=$1; shift
  local v; v=$(rate "$@")
  best[$key]=$(python3 -c "print(max(${best[$key]:-0}, $v))")
}
echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
for r in $(seq "$rounds"); do
  for m in fmf.btfpkg w.btf mlvq.btfpkg; do
    f=$dir/$m
    for t in 1 2; do
      measure "$m old det eval $t" "$old" -q bench eval "$f" --threads $t
      measure "$m new det eval $t" "$new" -q bench eval "$f" --filter deterministic --threads $t
      measure "$m new sto eval $t" "$new" -q bench eval "$f" --filter stochastic --threads $t
      measure "$m new sto sample $t" "$new" -q bench sample "$f" --filter stochastic --threads $t
    done
    measure "$m old det sample 1" "$old" -q bench sample "$f"
    measure "$m new det sample 1" "$new" -q bench sample "$f" --filter deterministic
    measure "$m new eval-sample 1" "$new" -q bench eval-sample "$f"
  done
done
for k in "${!best[@]}"; do echo "$k ${best[$k]}"; done | sort
