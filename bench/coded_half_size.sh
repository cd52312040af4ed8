#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Coded factors against f16 at half the bytes (issue 23, first measurements; docs/benchmarks.md,
# "Rate–distortion with coded factors"). For each synthetic preset at SIZE² × 81 × 81 and the real
# measured view: fmf with f16 factors at C = 8 and 16 (rmse) or 4, 8 and 16 (de2000), then fmf
# with coded factors from C = 32 (rmse) or 48 (de2000) at half of that package's size
# (--target-size, which chooses the components and the quality). METRIC rmse: the RMSE over every
# sample that btf compress reports; de2000: mean CIEDE2000 over every sample, by btf quality.
# Usage:
#   bash bench/coded_half_size.sh [build-dir] [size] [rmse|de2000]
set -euo pipefail
build=${1:-build/release}
size=${2:-128}
metric=${3:-rmse}
btf="$build/btf"
work=$(mktemp -d /tmp/btfkit_coded_XXXXXX)
trap 'rm -rf "$work"' EXIT
real="$(dirname "$0")/../../shared/data/ubo2003-proposte-view000"

case "$metric" in
  rmse) counts="8 16"; most=32; name="RMSE" ;;
  de2000) counts="4 8 16"; most=48; name="mean ΔE00" ;;
  *) echo "coded_half_size: metric '$metric' is not rmse or de2000" >&2; exit 1 ;;
esac
# error SOURCE PACKAGE COMPRESS-OUTPUT → the metric
error() {
  if [ "$metric" = rmse ]; then
    echo "$3" | grep -o 'RMSE [0-9.e-]*' | cut -d' ' -f2
  else
    "$btf" --quiet quality "$1" "$2" --metrics de2000 --json |
      python3 -c 'import json,sys; print("%.3f" % json.load(sys.stdin)["de2000"]["mean"])'
  fi
}
flags=()
[ "$metric" = rmse ] || flags=(--no-error)
echo "| material | C (f16) | f16 bytes | f16 $name | coded bytes | coded $name | coded choice |"
echo "|---|---|---|---|---|---|---|"
for m in woven_fabric embroidered_linen knitted_wool leather ceramic_tiles brushed_metal lacquered_wood real; do
  if [ "$m" = real ]; then
    [ -d "$real" ] || continue
    src="$real"
  else
    src="$work/$m.h5"
    "$btf" -q synth --preset "$m" --size "$size" -o "$src"
  fi
  for c in $counts; do
    o16=$("$btf" -q compress "$src" --codec fmf --components "$c" "${flags[@]}" -o "$work/f16.btfpkg")
    b16=$(stat -c %s "$work/f16.btfpkg")
    out=$("$btf" -q compress "$src" --codec fmf --components "$most" --quantize coded "${flags[@]}" \
      --target-size $((b16 / 2)) -o "$work/coded.btfpkg")
    bc=$(stat -c %s "$work/coded.btfpkg")
    choice=$(echo "$out" | grep -o "[0-9]* of $most components at quality [0-9.]*")
    echo "| $m | $c | $b16 | $(error "$src" "$work/f16.btfpkg" "$o16") | $bc | $(error "$src" "$work/coded.btfpkg" "$out") | $choice |"
  done
done
