#!/usr/bin/env bash
# Coded factors against f16 at half the bytes (issue 23, first measurements; docs/benchmarks.md,
# "Rate–distortion with coded factors"). For each synthetic preset at SIZE² × 81 × 81 and the real
# measured view: fmf with f16 factors at C = 8 and 16 (the old storage), then fmf with coded
# factors from C = 32 at half of that package's size (--target-size), and the RMSE over every
# sample that btf compress reports for each. Usage:
#   bash bench/coded_half_size.sh [build-dir] [size]
set -euo pipefail
build=${1:-build/release}
size=${2:-128}
btf="$build/btf"
work=$(mktemp -d /tmp/btfkit_coded_XXXXXX)
trap 'rm -rf "$work"' EXIT
real="$(dirname "$0")/../../shared/data/ubo2003-proposte-view000"

rmse() { grep -o 'RMSE [0-9.e-]*' | cut -d' ' -f2; }
echo "| material | C (f16) | f16 bytes | f16 RMSE | coded bytes | coded RMSE | coded choice |"
echo "|---|---|---|---|---|---|---|"
for m in woven_fabric embroidered_linen knitted_wool leather ceramic_tiles brushed_metal lacquered_wood real; do
  if [ "$m" = real ]; then
    [ -d "$real" ] || continue
    src="$real"
  else
    src="$work/$m.h5"
    "$btf" -q synth --preset "$m" --size "$size" -o "$src"
  fi
  for c in 8 16; do
    e16=$("$btf" -q compress "$src" --codec fmf --components "$c" -o "$work/f16.btfpkg" | rmse)
    b16=$(stat -c %s "$work/f16.btfpkg")
    out=$("$btf" -q compress "$src" --codec fmf --components 32 --quantize coded \
      --target-size $((b16 / 2)) -o "$work/coded.btfpkg")
    bc=$(stat -c %s "$work/coded.btfpkg")
    choice=$(echo "$out" | grep -o '[0-9]* of 32 components at quality [0-9.]*')
    echo "| $m | $c | $b16 | $e16 | $bc | $(echo "$out" | rmse) | $choice |"
  done
done
