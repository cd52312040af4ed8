#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# High-frequency omission of the perceptual codec (docs/benchmarks.md, "High-frequency
# omission"): package size and BTF-CIELab error against the base quality bq, with spatial levels
# only, angular levels only, and both. Usage:
#   bash bench/perceptual_omission.sh [build-dir] [components] [synthetic size] [grid] [preset]
set -euo pipefail
build=${1:-build/release}
components=${2:-32}
size=${3:-64}
grid=${4:-3}
preset=${5:-woven_fabric}
btf="$build/btf"
work=$(mktemp -d /tmp/btfkit_omission_XXXXXX)
trap 'rm -rf "$work"' EXIT

ref="$work/ref.h5"
"$btf" --quiet synth --preset "$preset" --size "$size" -o "$ref"
bytes() { stat -c %s "$1"; }
measure() {  # reference package → "rmse btf-cielab-mean"
  "$btf" --quiet quality "$1" "$2" --metrics rmse,btf-cielab --grid "$grid" --json |
    python3 -c 'import json,sys; j=json.load(sys.stdin); print("%.4f %.3f" % (j["rmse"], j["btf_cielab"]["mean"]))'
}
run() {  # label bq max-level max-angular-level
  local start end
  start=$(date +%s.%N)
  "$btf" --quiet compress "$ref" -o "$work/p.btfpkg" --codec perceptual --components "$components" \
    -p base-quality="$2" -p max-level="$3" -p max-angular-level="$4" --no-error >/dev/null
  end=$(date +%s.%N)
  read -r rmse cie <<<"$(measure "$ref" "$work/p.btfpkg")"
  local b
  b=$(bytes "$work/p.btfpkg")
  printf '| %s | %s | %s B | %.0f %% | %s | %s | %.1f s |\n' "$1" "$2" "$b" \
    "$(python3 -c "print(100 * $b / $full)")" "$rmse" "$cie" "$(python3 -c "print($end - $start)")"
}

echo "$preset ${size}² × 81 × 81, perceptual C = $components (10 px/°, 100 °/s), BTF-CIELab on a $grid × $grid grid"
echo
echo "| omission | bq | package | of bq = 1 | RMSE | BTF-CIELab mean ΔE00 | encode |"
echo "|---|---|---|---|---|---|---|"
"$btf" --quiet compress "$ref" -o "$work/full.btfpkg" --codec perceptual --components "$components" --no-error >/dev/null
full=$(bytes "$work/full.btfpkg")
run "none" 1 3 2
for q in 0.999 0.99 0.95; do
  run "spatial (max-level 3)" "$q" 3 0
  run "angular (max-angular-level 2)" "$q" 0 2
  run "both" "$q" 3 2
done
