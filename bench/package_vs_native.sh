#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The Debian package's btf (x86-64 baseline code, the `package` preset) against the development
# build's (-march=native, the `release` preset) on this machine: fmf compression of a
# SIZE² × 81 × 81 woven_fabric and random evaluation of its package, one thread each, best of
# REPEAT runs, the two binaries alternating (docs/benchmarks.md, "The Debian package's code").
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
"$native" -q compress "$work/m.h5" -o "$work/m.btfpkg" --codec fmf --components 16 --no-error

seconds() { /usr/bin/time -f %e "$@" 2>&1 >/dev/null | tail -1; }
best() { sort -g | head -1; }
declare -A compress eval
for b in native package; do compress[$b]=""; eval[$b]=""; done
for ((i = 0; i < repeat; i++)); do
  for b in native package; do
    bin=$native; [[ $b == package ]] && bin=$package
    compress[$b]+="$(seconds "$bin" -q --threads 1 compress "$work/m.h5" -o "$work/$b.btfpkg" \
      --codec fmf --components 16 --no-error) "
    eval[$b]+="$("$bin" -q bench eval "$work/m.btfpkg" --repeat 1 --json |
      python3 -c 'import json,sys; print(1e9 / json.load(sys.stdin)["evals_per_s"])') "
  done
done
echo "native: $("$native" --verbose formats 2>&1 >/dev/null | head -1)"
echo "package: $("$package" --verbose formats 2>&1 >/dev/null | head -1)"
printf '| | native (release) | package | package / native |\n|---|---|---|---|\n'
cn=$(tr ' ' '\n' <<<"${compress[native]}" | grep . | best)
cp=$(tr ' ' '\n' <<<"${compress[package]}" | grep . | best)
en=$(tr ' ' '\n' <<<"${eval[native]}" | grep . | best)
ep=$(tr ' ' '\n' <<<"${eval[package]}" | grep . | best)
printf '| fmf compress, %s² × 81 × 81, C = 16, 1 thread (s) | %s | %s | %.2f |\n' "$size" "$cn" "$cp" \
  "$(bc -l <<<"$cp / $cn")"
printf '| random eval of its package, 1 thread (ns per query) | %.1f | %.1f | %.2f |\n' "$en" "$ep" \
  "$(bc -l <<<"$ep / $en")"
