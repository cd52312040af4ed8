#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Renders every synthetic preset on a sphere, a cloth drape and a torus under the procedural sky
# and writes docs/images/gallery/<preset>.png plus docs/gallery.md. Each material is synthesized
# at 128² texels, compressed with fmf (32 components) and rendered by `btf render` (path tracing,
# 64 samples per pixel). Usage: bash scripts/gallery.sh [build/release/btf]
set -euo pipefail
btf=${1:-build/release/btf}
root=$(cd "$(dirname "$0")/.." && pwd)
images="$root/docs/images/gallery"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$images"

page="$work/gallery.md"
cat > "$page" <<'MD'
# Gallery

Every synthetic preset of `btf synth` ([synth.md](synth.md)) at 128² texels × 81 views × 81
lights, compressed with fmf (32 components, rgb) and path traced by `btf render` on a sphere, a
cloth drape (an open cylinder) and a torus on a grey floor under the procedural sky (sun at 40°
elevation): 480 × 320 pixels, 64 samples per pixel, tone-mapped. Made by
`bash scripts/gallery.sh build/release/btf`, which writes these pictures and this page.

MD

for preset in $("$btf" synth --list | awk '{print $1}'); do
  "$btf" --quiet synth --preset "$preset" --size 128 --seed 1 -o "$work/m.h5"
  "$btf" --quiet compress "$work/m.h5" --codec fmf --components 32 -p colour=rgb \
    -o "$work/$preset.btfpkg" --no-error > /dev/null
  cat > "$work/$preset.json" <<JSON
{
  "camera": {"position": [0, 1.5, 4.6], "look_at": [0, 0.5, 0], "fov": 32, "width": 480, "height": 320},
  "render": {"integrator": "path", "spp": 64, "max_depth": 6},
  "objects": [
    {"shape": "sphere", "radius": 0.5, "position": [-1.05, 0.5, 0], "uv_scale": [6, 3],
     "material": {"type": "btf", "file": "$preset.btfpkg"}},
    {"shape": "cylinder", "radius": 0.42, "height": 1.1, "position": [0.05, 0.55, -0.3], "uv_scale": [5, 2],
     "material": {"type": "btf", "file": "$preset.btfpkg"}},
    {"shape": "torus", "major_radius": 0.42, "minor_radius": 0.16, "position": [1.05, 0.16, 0.25],
     "uv_scale": [8, 2], "material": {"type": "btf", "file": "$preset.btfpkg"}},
    {"shape": "plane", "width": 14, "depth": 14, "material": {"type": "diffuse", "albedo": 0.35}}
  ],
  "lights": [{"type": "environment", "sky": {"sun_elevation": 40, "sun_azimuth": 60}}]
}
JSON
  "$btf" --quiet render "$work/$preset.json" -o "$images/$preset.png"
  description=$("$btf" synth --list | awk -v p="$preset" '$1 == p {$1 = ""; sub(/^ +/, ""); print}')
  printf '## %s\n\n%s\n\n![%s](images/gallery/%s.png)\n\n' \
    "$preset" "$description" "$preset" "$preset" >> "$page"
  echo "gallery: $preset"
done
cp "$page" "$root/docs/gallery.md"
echo "gallery: docs/gallery.md"
