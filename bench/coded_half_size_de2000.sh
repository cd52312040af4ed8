#!/usr/bin/env bash
# Coded factors against f16 at half the bytes, judged by mean CIEDE2000 over every sample
# (issue 23; docs/benchmarks.md, "Rate–distortion with coded factors"). For each synthetic preset
# at SIZE² × 81 × 81 and the real measured view: fmf with f16 factors at C = 4, 8 and 16, then
# fmf with coded factors from C = 48 at half of that package's size (--target-size); mean ΔE00
# of each by `btf quality --metrics de2000`. Usage:
#   bash bench/coded_half_size_de2000.sh [build-dir] [size]
set -euo pipefail
build=${1:-build/release}
size=${2:-128}
btf="$build/btf"
work=$(mktemp -d /tmp/btfkit_coded_de_XXXXXX)
trap 'rm -rf "$work"' EXIT
real="$(dirname "$0")/../../shared/data/ubo2003-proposte-view000"

de2000() {  # reference package → mean ΔE00
  "$btf" --quiet quality "$1" "$2" --metrics de2000 --json |
    python3 -c 'import json,sys; print("%.3f" % json.load(sys.stdin)["de2000"]["mean"])'
}
echo "| material | C (f16) | f16 bytes | f16 mean ΔE00 | coded bytes | coded mean ΔE00 | coded choice |"
echo "|---|---|---|---|---|---|---|"
for m in woven_fabric embroidered_linen knitted_wool leather ceramic_tiles brushed_metal lacquered_wood real; do
  if [ "$m" = real ]; then
    [ -d "$real" ] || continue
    src="$real"
  else
    src="$work/$m.h5"
    "$btf" -q synth --preset "$m" --size "$size" -o "$src"
  fi
  for c in 4 8 16; do
    "$btf" -q compress "$src" --codec fmf --components "$c" --no-error -o "$work/f16.btfpkg" > /dev/null
    b16=$(stat -c %s "$work/f16.btfpkg")
    out=$("$btf" -q compress "$src" --codec fmf --components 48 --quantize coded --no-error \
      --target-size $((b16 / 2)) -o "$work/coded.btfpkg")
    bc=$(stat -c %s "$work/coded.btfpkg")
    choice=$(echo "$out" | grep -o '[0-9]* of 48 components at quality [0-9.]*')
    echo "| $m | $c | $b16 | $(de2000 "$src" "$work/f16.btfpkg") | $bc | $(de2000 "$src" "$work/coded.btfpkg") | $choice |"
  done
done
