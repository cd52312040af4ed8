#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# mlvq against fmf and lpca at comparable package size (docs/benchmarks.md, "mlvq"): for each
# material compress with mlvq at a threshold, then with fmf and lpca at the component count whose
# package is closest in size, and measure all three with `btf quality` (RMSE, MSSIM on Y,
# BTF-CIELab on a grid × grid of viewing conditions). Usage:
#   bash bench/mlvq_vs_fmf_lpca.sh [build-dir] [threshold] [synthetic size] [grid] [presets...]
# REAL=0 leaves out the real measured view.
set -euo pipefail
build=${1:-build/release}
threshold=${2:-3e-5}
size=${3:-128}
grid=${4:-3}
shift $(( $# < 4 ? $# : 4 ))
presets=("$@")
[ ${#presets[@]} -eq 0 ] && presets=(woven_fabric leather)
btf="$build/btf"
work=$(mktemp -d /tmp/btfkit_mlvq_XXXXXX)
trap 'rm -rf "$work"' EXIT
real="$(dirname "$0")/../../shared/data/ubo2003-proposte-view000"

bytes() { stat -c %s "$1"; }
measure() {  # reference package → "rmse mssim(Y) btf-cielab-mean"
  "$btf" --quiet quality "$1" "$2" --metrics rmse,ssim,btf-cielab --grid "$grid" --json |
    python3 -c 'import json,sys; j=json.load(sys.stdin)
print("%.4f %.4f %.3f" % (j["rmse"], j["ssim"]["Y"], j["btf_cielab"]["mean"]))'
}
closest() {  # reference codec target-bytes → the component count whose package is closest
  # (sizes grow with the count: bisect for the first count at or above the target, then take it
  # or the one below)
  local ref=$1 codec=$2 target=$3 lo=1 hi=128 mid s
  size_of() {
    "$btf" --quiet compress "$ref" -o "$work/c.btfpkg" --codec "$codec" --components "$1" --no-error >/dev/null
    bytes "$work/c.btfpkg"
  }
  if [ "$(size_of $hi)" -lt "$target" ]; then echo $hi; return; fi
  while [ $lo -lt $hi ]; do
    mid=$(( (lo + hi) / 2 ))
    if [ "$(size_of $mid)" -lt "$target" ]; then lo=$((mid + 1)); else hi=$mid; fi
  done
  if [ "$lo" -gt 1 ]; then
    local above below
    above=$(size_of "$lo"); below=$(size_of $((lo - 1)))
    if [ $((target - below)) -lt $((above - target)) ]; then lo=$((lo - 1)); fi
  fi
  echo "$lo"
}

echo "mlvq threshold = chroma-threshold = $threshold (other parameters default); fmf rgb, lpca 7 clusters"
echo
echo "| material | codec | setting | package | ratio | encode | RMSE | MSSIM (Y) | BTF-CIELab mean ΔE00 |"
echo "|---|---|---|---|---|---|---|---|---|"
materials=()
if [ "${REAL:-1}" = 0 ]; then :
elif [ -d "$real" ]; then materials+=("real:$real"); else echo "(real view absent: $real)" >&2; fi
for p in "${presets[@]}"; do materials+=("$p"); done
for material in "${materials[@]}"; do
  if [[ $material == real:* ]]; then
    ref=${material#real:}; name="real view (UBO2003 proposte, 256², 1 view × 81 lights)"
    raw=$((256 * 256 * 81 * 3))
  else
    ref="$work/$material.h5"; name="$material ${size}² × 81 × 81"
    "$btf" --quiet synth --preset "$material" --size "$size" -o "$ref"
    raw=$((size * size * 81 * 81 * 3))
  fi
  start=$(date +%s.%N)
  "$btf" --quiet compress "$ref" -o "$work/m.btfpkg" --codec mlvq -p threshold="$threshold" \
    -p chroma-threshold="$threshold" --no-error >/dev/null
  m_time=$(python3 -c "print('%.1f s' % ($(date +%s.%N) - $start))")
  target=$(bytes "$work/m.btfpkg")
  row() {  # codec setting package time
    local b; b=$(bytes "$3")
    read -r rmse mssim cie <<<"$(measure "$ref" "$3")"
    echo "| $name | $1 | $2 | $b B | 1:$((raw / b)) | $4 | $rmse | $mssim | $cie |"
  }
  row mlvq "threshold $threshold" "$work/m.btfpkg" "$m_time"
  for codec in fmf lpca; do
    c=$(closest "$ref" "$codec" "$target")
    start=$(date +%s.%N)
    "$btf" --quiet compress "$ref" -o "$work/$codec.btfpkg" --codec "$codec" --components "$c" --no-error >/dev/null
    t=$(python3 -c "print('%.1f s' % ($(date +%s.%N) - $start))")
    row "$codec" "C = $c" "$work/$codec.btfpkg" "$t"
  done
done
