#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# fuzz/make_corpus.sh [BUILD]: rebuilds the seed corpora fuzz/corpus/<target>/ and the fixtures
# in fuzz/data/ from valid files written by the project's own writers: `btf synth` (HDF5),
# `btf compress` with every codec (packages), `btf bsvtf`, `btf convert` (UBO2014 DFMF), and
# BUILD/fuzz_make_seeds for what no command writes (tiles, a UBO2003 zip, image names).
# Materials are tiny (16² texels, 6 × 6 directions) so that each seed is a few KiB to ~100 KiB.
# `make fuzz-corpus` builds what it needs and runs it; BUILD defaults to build/release.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$(cd "${1:-$root/build/release}" && pwd)"
btf="$build/btf"
seeds="$build/fuzz_make_seeds"
for program in "$btf" "$seeds"; do
  [ -x "$program" ] || { echo "make_corpus: $program is missing" >&2; exit 1; }
done
corpus="$root/fuzz/corpus"
data="$root/fuzz/data"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# Keep each target's folder but replace what this script writes (files found by fuzzing and
# merged in with FUZZ_MERGE=1 stay).
put() {  # put TARGET NAME FILE
  mkdir -p "$corpus/$1"
  cp "$3" "$corpus/$1/$2"
}

# A small direction set: 6 views × 6 lights.
cat > "$tmp/dirs6.txt" << 'EOF'
0 0
30 0
30 120
30 240
60 60
60 180
EOF

# Raw BTFs (btfkit HDF5): half and float values, two presets.
"$btf" synth --preset woven_fabric --size 16 --sampling "$tmp/dirs6.txt" -o "$tmp/woven.h5" > /dev/null
"$btf" synth --preset woven_fabric --size 8 --sampling "$tmp/dirs6.txt" --float -o "$tmp/woven_f32.h5" > /dev/null
"$btf" synth --list > "$tmp/presets.txt"
other="$(awk 'NR > 1 && $1 != "woven_fabric" { print $1; exit }' "$tmp/presets.txt")"
"$btf" synth --preset "${other:-woven_fabric}" --size 16 --sampling "$tmp/dirs6.txt" --seed 2 -o "$tmp/other.h5" > /dev/null
for f in woven woven_f32 other; do put hdf5 "$f.h5" "$tmp/$f.h5"; done

# Packages: every codec, small settings.
compress() {  # compress NAME ARGS...
  local name="$1"
  shift
  "$btf" compress "$tmp/woven.h5" -o "$tmp/$name.btfpkg" --no-error "$@" > /dev/null
}
compress fmf --codec fmf --components 4
compress fmf_f32 --codec fmf --components 3 --quantize f32
compress fmf_raw --codec fmf --components 2 --zstd 0
compress fmf_coded --codec fmf --components 3 --quantize coded -p quality=30
compress pca_views --codec pca-views --components 3
compress lpca --codec lpca --components 3
compress perceptual --codec perceptual --components 6
compress perceptual_levels --codec perceptual --components 6 -p base-quality=0.3
compress pca_views_groups --codec pca-views --components 2 -p views-per-group=2
compress mlvq --codec mlvq -p n-theta-v=3 -p n-phi-v=4 -p n-alpha=3 -p n-beta=4
compress mlvq_isotropic --codec mlvq -p n-theta-v=3 -p n-phi-v=1 -p n-alpha=3 -p n-beta=4
put codec_fmf fmf.btfpkg "$tmp/fmf.btfpkg"
put codec_fmf fmf_f32.btfpkg "$tmp/fmf_f32.btfpkg"
put codec_fmf fmf_raw.btfpkg "$tmp/fmf_raw.btfpkg"
put codec_fmf fmf_coded.btfpkg "$tmp/fmf_coded.btfpkg"
put codec_pca_views pca_views.btfpkg "$tmp/pca_views.btfpkg"
put codec_lpca lpca.btfpkg "$tmp/lpca.btfpkg"
put codec_perceptual perceptual.btfpkg "$tmp/perceptual.btfpkg"
put codec_perceptual perceptual_levels.btfpkg "$tmp/perceptual_levels.btfpkg"
put codec_pca_views pca_views_groups.btfpkg "$tmp/pca_views_groups.btfpkg"
put codec_mlvq mlvq_isotropic.btfpkg "$tmp/mlvq_isotropic.btfpkg"
put codec_mlvq mlvq.btfpkg "$tmp/mlvq.btfpkg"
for f in fmf fmf_raw pca_views lpca perceptual mlvq; do put package "$f.btfpkg" "$tmp/$f.btfpkg"; done

# BSVTF files: DCT tiles and lossless ones.
"$btf" bsvtf "$tmp/fmf.btfpkg" -o "$tmp/fmf.bsvtf" --tile 8 --pad 4 > /dev/null
"$btf" bsvtf "$tmp/fmf.btfpkg" -o "$tmp/fmf_lossless.bsvtf" --tile 8 --pad 4 --lossless > /dev/null
put bsvtf fmf.bsvtf "$tmp/fmf.bsvtf"
put bsvtf fmf_lossless.bsvtf "$tmp/fmf_lossless.bsvtf"
put package fmf.bsvtf "$tmp/fmf.bsvtf"

# UBO2014 DFMF files: float32 and half factors, both colour models.
"$btf" convert "$tmp/woven.h5" "$tmp/model11.btf" --components 3 > /dev/null
"$btf" convert "$tmp/woven.h5" "$tmp/rgb_half.btf" --components 2 --colour rgb --half > /dev/null
put ubo2014 model11.btf "$tmp/model11.btf"
put ubo2014 rgb_half.btf "$tmp/rgb_half.btf"

# Tiles, coded factor sections, a UBO2003 archive, image names.
"$seeds" "$tmp/seeds"
for target in bsvtf_tile coded_component ubo2003_archive ubo2003_names utia_names; do
  for f in "$tmp/seeds/$target"/*; do put "$target" "$(basename "$f")" "$f"; done
done

# Fixtures the scene seeds refer to (relative paths resolve to fuzz/data/).
mkdir -p "$data"
cp "$tmp/fmf_raw.btfpkg" "$data/material.btfpkg"
cat > "$data/quad.obj" << 'EOF'
# a unit quad with texture coordinates
v 0 0 0
v 1 0 0
v 1 0 -1
v 0 0 -1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 1 0
f 1/1/1 2/2/1 3/3/1 4/4/1
EOF

# OBJ meshes.
cp "$data/quad.obj" "$tmp/quad.obj"
put obj quad.obj "$tmp/quad.obj"
cat > "$tmp/tetra.obj" << 'EOF'
o tetra
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
vt 0 0
vt 1 0
vt 0 1
f 1/1 3/3 2/2
f 1/1 2/2 4/3
f 1/1 4/3 3/3
f -3/-3 -2/-2 -1/-1
EOF
put obj tetra.obj "$tmp/tetra.obj"
cat > "$tmp/normals.obj" << 'EOF'
mtllib none.mtl
g group
usemtl x
v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5
vn 0 1 0
vn 0 0.7071 0.7071
f 1/1/1 2/2/1 3/3/1 4/4/1 5/5/2
s 1
f 1/1/2 5/5/2 2/2/2
EOF
put obj normals.obj "$tmp/normals.obj"

# Scenes.
cat > "$tmp/full.json" << 'EOF'
{
  "camera": {"position": [0, 1.2, 4], "look_at": [0, 0.4, 0], "fov": 35, "width": 8, "height": 8},
  "render": {"integrator": "path", "spp": 1, "max_depth": 3, "seed": 1, "exposure": 0},
  "objects": [
    {"shape": "sphere", "radius": 0.5, "position": [0, 0.5, 0], "uv_scale": 4, "segments": 8,
     "material": {"type": "btf", "file": "material.btfpkg"}},
    {"shape": "plane", "width": 10, "depth": 10, "material": {"type": "diffuse", "albedo": 0.5}},
    {"shape": "obj", "file": "quad.obj", "rotation": [0, 45, 0], "scale": [1, 2, 1],
     "uv_rotation": 30, "material": {"type": "btf", "file": "material.btfpkg"}}
  ],
  "lights": [
    {"type": "environment", "sky": {"sun_elevation": 35, "sun_azimuth": 45, "width": 16}},
    {"type": "point", "position": [1, 2, 1], "intensity": 10}
  ]
}
EOF
cat > "$tmp/shapes.json" << 'EOF'
{
  "render": {"integrator": "direct", "spp": 2},
  "objects": [
    {"shape": "cylinder", "radius": 1, "height": 2, "segments": 6,
     "material": {"type": "diffuse", "albedo": [0.2, 0.3, 0.4]}},
    {"shape": "torus", "major_radius": 1, "minor_radius": 0.3, "segments": 6, "name": "t",
     "material": {"type": "diffuse", "albedo": 0.8}}
  ],
  "lights": [
    {"type": "directional", "direction": [0, 1, 0.2], "irradiance": 3},
    {"type": "sphere", "center": [0, 3, 0], "radius": 0.5, "radiance": 100}
  ]
}
EOF
put scene full.json "$tmp/full.json"
put scene shapes.json "$tmp/shapes.json"

# Requests to the server (the request target, Range fields, a WebSocket handshake).
mkdir -p "$corpus/request"
printf 'GET /materials/a%%20b.btfpkg?x=1 HTTP/1.1\r\nHost: localhost\r\n\r\n' > "$corpus/request/get"
printf 'GET /a.bsvtf HTTP/1.1\r\nHost: h\r\nRange: bytes=0-99\r\n\r\n' > "$corpus/request/range"
printf 'GET /a HTTP/1.1\r\nRange: bytes=-500\r\nRange: BYTES=10-,20-30\r\n\r\n' > "$corpus/request/ranges"
printf 'GET /%%2e%%2e/etc/passwd HTTP/1.1\r\nRange: bytes=0-18446744073709551616\r\n\r\n' > "$corpus/request/traversal"
printf 'GET /ws HTTP/1.1\r\nHost: localhost:8080\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n' > "$corpus/request/handshake"

# Each seed must be valid as written: check it with the normal reader where there is one.
for f in "$corpus"/codec_*/*.btfpkg "$corpus"/bsvtf/*.bsvtf; do "$btf" info "$f" > /dev/null; done
du -sh "$corpus" "$data"
