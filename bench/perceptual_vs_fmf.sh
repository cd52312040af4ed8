#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Perceptually guided compression against plain fmf at equal package size, judged by BTF-CIELab
# (docs/benchmarks.md, "Quality (issue 4)"). For each material: compress with `perceptual` at
# C components, then with `fmf` at the component count whose package is closest in size, and
# measure both with `btf quality --metrics rmse,btf-cielab`. Usage:
#   bash bench/perceptual_vs_fmf.sh [build-dir] [components] [synthetic size] [grid]
set -euo pipefail
build=${1:-build/release}
components=${2:-16}
size=${3:-64}
grid=${4:-3}
btf="$build/btf"
work=$(mktemp -d /tmp/btfkit_percept_XXXXXX)
trap 'rm -rf "$work"' EXIT
real="$(dirname "$0")/../../shared/data/ubo2003-proposte-view000"

bytes() { stat -c %s "$1"; }
measure() {  # reference package → "rmse btf-cielab-mean condition"
  "$btf" --quiet quality "$1" "$2" --metrics rmse,btf-cielab --grid "$grid" --json |
    python3 -c 'import json,sys; j=json.load(sys.stdin); b=j["btf_cielab"]
print("%.4f %.3f ω=%.3g°/s,r_s=%.3g px/°" % (j["rmse"], b["mean"], b["angular_speed"], b["resolution"]))'
}

echo "| material | codec | components | package | RMSE | BTF-CIELab mean ΔE00 (worst condition) |"
echo "|---|---|---|---|---|---|"
materials=()
if [ -d "$real" ]; then materials+=("real:$real"); else echo "(real view absent: $real)" >&2; fi
materials+=("woven_fabric" "leather")
for material in "${materials[@]}"; do
  if [[ $material == real:* ]]; then
    ref=${material#real:}; name="real view (UBO2003 proposte, 256², 1 view × 81 lights)"
  else
    ref="$work/$material.h5"; name="$material ${size}² × 81 × 81"
    "$btf" --quiet synth --preset "$material" --size "$size" -o "$ref"
  fi
  "$btf" --quiet compress "$ref" -o "$work/p.btfpkg" --codec perceptual --components "$components" --no-error >/dev/null
  target=$(bytes "$work/p.btfpkg")
  # The fmf component count whose package is closest in size to the perceptual one.
  best=1; best_gap=-1
  for c in $(seq 1 $((components * 3))); do
    "$btf" --quiet compress "$ref" -o "$work/f.btfpkg" --codec fmf --components "$c" --no-error >/dev/null
    s=$(bytes "$work/f.btfpkg"); gap=$(( s > target ? s - target : target - s ))
    if [ "$best_gap" -lt 0 ] || [ "$gap" -lt "$best_gap" ]; then best=$c; best_gap=$gap; fi
    [ "$s" -gt "$target" ] && break
  done
  "$btf" --quiet compress "$ref" -o "$work/f.btfpkg" --codec fmf --components "$best" --no-error >/dev/null
  read -r p_rmse p_cie p_cond <<<"$(measure "$ref" "$work/p.btfpkg")"
  read -r f_rmse f_cie f_cond <<<"$(measure "$ref" "$work/f.btfpkg")"
  echo "| $name | perceptual | $components | $(bytes "$work/p.btfpkg") B | $p_rmse | $p_cie ($p_cond) |"
  echo "| | fmf | $best | $(bytes "$work/f.btfpkg") B | $f_rmse | $f_cie ($f_cond) |"
done
