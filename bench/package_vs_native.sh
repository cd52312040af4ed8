#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The Debian package's btf (x86-64 baseline code with run-time clones of the evaluators' hot
# functions, the `package` preset) against the development build's (-march=native, the `release`
# preset) on this machine, one thread each, best of REPEAT runs, the two binaries alternating:
# fmf compression of a SIZE² × 81 × 81 woven_fabric, then random evaluation (stochastic and
# deterministic filter) and light sampling of its package, and random evaluation of lpca's and
# mlvq's packages of it (docs/benchmarks.md, "The Debian package's code").
# Usage:
#   bash bench/package_vs_native.sh [size] [repeat]      (after `make` and `make package`)
set -euo pipefail
size=${1:-256}
repeat=${2:-3}
native=build/release/btf
package=build/package/btf
for b in "$native" "$package"; do
  [[ -x $b ]] || { echo "package_vs_native: $b is missing (make, make package)" >&2; exit 1; }
done
work=$(mktemp -d /tmp/btfkit_pkgbench_XXXXXX)
trap 'rm -rf "$work"' EXIT

"$native" -q synth --preset woven_fabric --size "$size" -o "$work/m.h5"
for codec in fmf lpca mlvq; do
  options=(--components 16)
  [[ $codec == mlvq ]] && options=()
  "$native" -q compress "$work/m.h5" -o "$work/$codec.btfpkg" --codec "$codec" "${options[@]}" \
    --no-error
done

seconds() { /usr/bin/time -f %e "$@" 2>&1 >/dev/null | tail -1; }
# Nanoseconds per query of `btf bench WHAT FILE [options]`.
per_query() {
  local bin=$1 what=$2 file=$3
  shift 3
  "$bin" -q bench "$what" "$file" --repeat 1 --json "$@" |
    python3 -c 'import json,sys; j = json.load(sys.stdin); print(1e9 / j.get("evals_per_s", j.get("samples_per_s")))'
}
rows=("fmf compress, ${size}² × 81 × 81, C = 16 (s)"
      "fmf random eval, stochastic filter (ns per query)"
      "fmf random eval, deterministic filter (ns per query)"
      "fmf light sampling, stochastic filter (ns per sample)"
      "lpca random eval, stochastic filter (ns per query)"
      "mlvq random eval, stochastic filter (ns per query)")
measure() {  # row index, binary
  local bin=$2
  case $1 in
    0) seconds "$bin" -q --threads 1 compress "$work/m.h5" -o "$work/out.btfpkg" --codec fmf \
         --components 16 --no-error ;;
    1) per_query "$bin" eval "$work/fmf.btfpkg" ;;
    2) per_query "$bin" eval "$work/fmf.btfpkg" --filter deterministic ;;
    3) per_query "$bin" sample "$work/fmf.btfpkg" ;;
    4) per_query "$bin" eval "$work/lpca.btfpkg" ;;
    5) per_query "$bin" eval "$work/mlvq.btfpkg" ;;
  esac
}
declare -A times
for ((r = 0; r < ${#rows[@]}; r++)); do times[$r,native]=""; times[$r,package]=""; done
for ((i = 0; i < repeat; i++)); do
  for ((r = 0; r < ${#rows[@]}; r++)); do
    times[$r,native]+="$(measure "$r" "$native") "
    times[$r,package]+="$(measure "$r" "$package") "
  done
done
best() { tr ' ' '\n' <<<"$1" | grep . | sort -g | head -1; }
echo "native: $("$native" --verbose formats 2>&1 >/dev/null | head -1)"
echo "package: $("$package" --verbose formats 2>&1 >/dev/null | head -1)"
printf '| one thread | native (release) | package | package / native |\n|---|---|---|---|\n'
for ((r = 0; r < ${#rows[@]}; r++)); do
  n=$(best "${times[$r,native]}")
  p=$(best "${times[$r,package]}")
  printf '| %s | %.2f | %.2f | %.2f |\n' "${rows[$r]}" "$n" "$p" "$(bc -l <<<"$p / $n")"
done
