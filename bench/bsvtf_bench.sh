#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# BSVTF benchmarks for docs/benchmarks.md (issue 8), with the headless simulator:
#   bash bench/bsvtf_bench.sh [build-dir] [out-dir] [texels] [materials]
# Makes `materials` synthetic materials of texels² (7 presets, seeds 1, 2, …) on a reduced
# sampling of 25 views × 25 lights, fmf with 16 components in half floats, preprocesses each
# (btf bsvtf: the time per material), puts them on a grid of spheres and tori under a
# directional light, and runs btf bsvtf-sim:
#   1. memory with 1, 5, 10 and all materials (tile cache 2048², unlimited link);
#   2. quality along a fly-through at cache sizes 1024², 2048², 4096² (unlimited link: every
#      frame shows what a cache of that size holds);
#   3. streaming over 10 Mbit/s with a fixed camera: SSIM against the full-FMF frame as bytes
#      arrive (stream.csv).
set -euo pipefail
build=${1:-build/release}
out=${2:-out/bsvtf-bench}
size=${3:-512}
count=${4:-20}
btf=$(cd "$build" && pwd)/btf
mkdir -p "$out"
cd "$out"

# 25 directions: the pole and rings at 25°, 45° and 65° (6, 8 and 10 azimuths).
{
  echo "0 0"
  for p in 0 60 120 180 240 300; do echo "25 $p"; done
  for p in 0 45 90 135 180 225 270 315; do echo "45 $p"; done
  for p in 0 36 72 108 144 180 216 252 288 324; do echo "65 $p"; done
} > sampling25.txt

presets=(woven_fabric leather knitted_wool lacquered_wood ceramic_tiles brushed_metal embroidered_linen)
echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores; $count materials of ${size}² texels, 25 × 25 directions, fmf 16 components f16"
echo "## preprocessing (btf bsvtf, tiles 64 + 4, tile error 0.01)"
for ((i = 0; i < count; ++i)); do
  preset=${presets[$((i % 7))]}
  seed=$((i / 7 + 1))
  name=m$i
  if [ ! -f "$name.btfpkg" ]; then
    "$btf" -q synth --preset "$preset" --size "$size" --sampling sampling25.txt --seed "$seed" -o "$name.h5"
    "$btf" -q compress "$name.h5" --codec fmf --components 16 --quantize f16 --no-error -o "$name.btfpkg" > /dev/null
    rm -f "$name.h5"
  fi
  echo "$name ($preset, seed $seed): $("$btf" -q bsvtf "$name.btfpkg" -o "$name.bsvtf" | tr '\n' ' ')"
done

# A grid of objects, 5 per row, alternately spheres and tori, on a floor.
scene() {  # materials → scene JSON
  local n=$1 objects="" x z shape
  for ((i = 0; i < n; ++i)); do
    x=$(( (i % 5) * 3 - 6 )); z=$(( -(i / 5) * 3 ))
    if (( i % 2 == 0 )); then shape='"shape": "sphere", "radius": 1.1'; else shape='"shape": "torus", "major_radius": 1.0, "minor_radius": 0.4, "rotation": [60, 0, 0]'; fi
    objects+="{$shape, \"position\": [$x, 1.2, $z], \"uv_scale\": [3, 2], \"material\": {\"type\": \"btf\", \"file\": \"m$i.btfpkg\"}},"
  done
  cat <<JSON
{"camera": {"position": [0, 6, 12], "look_at": [0, 0, -4], "fov": 45, "width": 480, "height": 270},
 "objects": [$objects {"shape": "plane", "width": 40, "depth": 40, "material": {"type": "diffuse", "albedo": 0.3}}],
 "lights": [{"type": "directional", "direction": [-0.4, 1, 0.7], "irradiance": 3}]}
JSON
}
# The fly-through: from the overview down the rows to a close-up, 90 frames at 30 per second.
cat > flythrough.json <<'JSON'
{"frames": 90, "keys": [
  {"frame": 0, "position": [0, 6, 12], "look_at": [0, 0, -4]},
  {"frame": 45, "position": [-3, 3, 3], "look_at": [-3, 1, -3]},
  {"frame": 89, "position": [-5.2, 1.8, 1.1], "look_at": [-6, 1.2, 0]}]}
JSON
cat > still.json <<'JSON'
{"frames": 450, "keys": [{"frame": 0, "position": [-1, 4, 6], "look_at": [-3, 1, -2]}]}
JSON
cat > short.json <<'JSON'
{"frames": 2, "keys": [{"frame": 0, "position": [0, 6, 12], "look_at": [0, 0, -4]}]}
JSON

echo; echo "## 1. memory (cache 2048², unlimited link)"
for n in 1 5 10 "$count"; do
  (( n > count )) && continue
  scene "$n" > scene$n.json
  echo "$n materials: $("$btf" -q bsvtf-sim --scene scene$n.json --path short.json --cache 2048 --bandwidth unlimited | grep '^memory')"
done

echo; echo "## 2. quality along the fly-through (unlimited link)"
scene "$count" > scene.json
for cache in 1024 2048 4096; do
  echo "cache ${cache}²: $("$btf" -q bsvtf-sim --scene scene.json --path flythrough.json --cache "$cache" --bandwidth unlimited --log quality$cache.csv | tr '\n' ' ')"
done

echo; echo "## 3. streaming over 10 Mbit/s, fixed camera, cache 4096²"
"$btf" -q bsvtf-sim --scene scene.json --path still.json --cache 4096 --bandwidth 10mbit --log stream.csv --plot stream.svg
