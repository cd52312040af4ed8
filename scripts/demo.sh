#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The main job of `make demo`: btf serve streams btfkit's built-in demo material to the web viewer
# (its URL is printed as soon as it is up, and it serves until Ctrl-C). Meanwhile the script
# synthesizes the default material, describes it, writes pictures of it at measured and
# in-between directions, compresses it and shows what the package costs and loses, renders it on
# objects under a sky, and writes a report comparing codecs.
#
# DEMO_PORT (8080) is the server's port; DEMO_SERVE=0 stops the server when the pictures and the
# report are done instead of serving until Ctrl-C (for unattended runs).
set -euo pipefail
btf=${1:-build/release/btf}
out=${DEMO_OUT:-out/demo}
preset=${DEMO_PRESET:-woven_fabric}
size=${DEMO_SIZE:-128}
port=${DEMO_PORT:-8080}
mkdir -p "$out"

step() { printf '\n== %s\n' "$*"; }

step "Starting the streaming server: btf serve, the built-in demo material (made on the first start, about a minute; cached)"
rm -f "$out/serve.out"
"$btf" serve --port "$port" > "$out/serve.out" 2> "$out/serve.log" &
server=$!
stop_server() {
  if kill -0 "$server" 2> /dev/null; then
    kill -TERM "$server" 2> /dev/null || true
    wait "$server" 2> /dev/null || true
  fi
}
trap stop_server EXIT
trap 'exit 130' INT TERM
url=""
for _ in $(seq 1 1200); do
  url=$(sed -n 's/^serving .* at \(http:[^ ]*\)$/\1/p' "$out/serve.out")
  [ -n "$url" ] && break
  if ! kill -0 "$server" 2> /dev/null; then
    echo "demo: btf serve stopped before serving:" >&2
    cat "$out/serve.log" >&2
    exit 1
  fi
  sleep 0.5
done
[ -n "$url" ] || { echo "demo: btf serve did not start within 10 minutes ($out/serve.log)" >&2; exit 1; }
cat "$out/serve.out"
printf '\n   >>> The web viewer: open %s in a browser (WebGL2). <<<\n' "$url"
printf '   The server runs while the rest of the demo makes pictures and a report.\n'

step "Synthesizing the default material: $preset, ${size}² texels, 81 lights × 81 views (UBO2003 sampling)"
"$btf" synth --preset "$preset" --size "$size" --sampling ubo81 --seed 1 -o "$out/$preset.h5"

step "btf info"
"$btf" info "$out/$preset.h5"

step "Slices: images at measured and in-between (interpolated) directions"
slice() {  # light view name
  "$btf" slice "$out/$preset.h5" --light "$1" --view "$2" -o "$out/${preset}_$3.png"
}
slice 0,0 0,0 light0_view0
slice 60,0 0,0 light60_view0
slice 75,180 30,0 light75-180_view30
slice 45,90 45,270 mirror45
slice 37,100 22,10 between_samples
"$btf" slice "$out/$preset.h5" --texel $((size / 2)),$((size / 2)) --scale 4 \
  -o "$out/${preset}_abrdf.png"

step "Compressing it: fmf (one truncated SVD of the whole BTF), 32 components, half-float factors"
"$btf" compress "$out/$preset.h5" -o "$out/$preset.btfpkg" --codec fmf --components 32 --quantize f16

step "btf info of the package"
"$btf" info "$out/$preset.btfpkg"

step "btf eval: the package's linear RGB value between measured directions"
"$btf" eval "$out/$preset.btfpkg" --uv 0.5,0.5 --light 37,100 --view 22,10

step "Rendering it: a sphere and a cloth drape under a sky, path traced (btf render, docs/scenes.md)"
cat > "$out/scene.json" <<EOF
{
  "camera": {"position": [0, 1.4, 4.2], "look_at": [0, 0.55, 0], "fov": 30, "width": 480, "height": 320},
  "render": {"integrator": "path", "spp": 32, "max_depth": 6},
  "objects": [
    {"name": "sphere", "shape": "sphere", "radius": 0.55, "position": [-0.75, 0.55, 0],
     "uv_scale": [6, 3], "material": {"type": "btf", "file": "$preset.btfpkg"}},
    {"name": "cloth drape", "shape": "cylinder", "radius": 0.45, "height": 1.2,
     "position": [0.75, 0.6, 0], "uv_scale": [5, 2], "material": {"type": "btf", "file": "$preset.btfpkg"}},
    {"name": "floor", "shape": "plane", "width": 12, "depth": 12,
     "material": {"type": "diffuse", "albedo": 0.35}}
  ],
  "lights": [{"type": "environment", "sky": {"sun_elevation": 40, "sun_azimuth": 60}}]
}
EOF
"$btf" render "$out/scene.json" -o "$out/${preset}_render.png"

step "The uncompressed material against the package on the same objects (btf render --compare)"
"$btf" render "$out/scene.json" --compare "$out/$preset.h5" "$out/$preset.btfpkg" --spp 16 \
  -o "$out/${preset}_compare.png"

step "A compression report: four configurations, every image measured, the scene rendered with each"
"$btf" report "$out/$preset.h5" --codecs fmf:C=8,32 pca-views:k=1,C=8 mlvq \
  --btf-cielab-grid 1 --scene "$out/scene.json" --render-spp 16 --force -o "$out/report"
echo "Open file://$(cd "$out/report" && pwd)/index.html in a browser (it needs no network)."

real=../shared/data/ubo2003-proposte-view000
if [ -d "$real" ]; then
  step "The real measured view next to it (UBO2003, one view of 81)"
  "$btf" info "$real" --sample 27
  "$btf" slice "$real" --light 60,0 --view 0,0 -o "$out/real_light60_view0.png"
fi

step "Done. Pictures and the material are in $out/:"
ls -1 "$out"

if [ "${DEMO_SERVE:-1}" = 0 ]; then
  stop_server
  echo "demo: the server at $url stopped (DEMO_SERVE=0)"
  exit 0
fi
step "Serving: open $url in a browser; Ctrl-C stops the server"
wait "$server"
