#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# UBO2014 files as they are (docs/benchmarks.md, "Viewer: every codec"):
#   bash bench/ubo2014_bench.sh [build-dir] [out-dir] [size] [components] [runs]
# For a DFMF file of size² texels on the 151-direction dome with `components` half-float
# components per channel (colour models 0 and 11; random factors written by
# `ubo2014_files write`, see bench/ubo2014_files.cpp), measures:
#   1. `btf convert X.btf X.btfpkg` (the package of the file's own factors): wall time and peak
#      memory (/usr/bin/time), best of `runs`;
#   2. serve start: from launching `btf serve X.btf --port 0` until `GET api/materials` answers,
#      with an empty cache folder (the package is made first) and with the warm cache (the
#      package made by the previous start is reused), best of `runs` each;
#   3. `btf eval X.btf` of one query (the whole process: read, build the evaluator, one value)
#      and of X.btfpkg: wall time and peak memory, best of `runs`;
#   4. eval() throughput on the file (ubo2014_files eval): the fmf evaluator against the
#      RGB-interpolating material, in the same run.
# Needs the btf and ubo2014_files programs (make bench builds both) and curl.
set -euo pipefail
build=${1:-build/release}
out=${2:-out/ubo2014-bench}
size=${3:-256}
components=${4:-32}
runs=${5:-3}
btf=$(cd "$build" && pwd)/btf
files=$(cd "$build" && pwd)/ubo2014_files
mkdir -p "$out"
cd "$out"

now() { date +%s.%N; }
# best (smallest) of the numbers on stdin
best() { sort -g | head -1; }
# `/usr/bin/time` of a command: "seconds peak-KB" on stdout, the command's output discarded.
timed() { /usr/bin/time -f "%e %M" -o time.txt "$@" > /dev/null 2>&1; cat time.txt; }

# Seconds from launching `btf serve $1` (cache folder $2) until the material list answers.
serve_start() {
  local input=$1 cache=$2 start pid url="" t
  start=$(now)
  BTF_CACHE_DIR=$cache "$btf" -q serve "$input" --port 0 > serve.out 2>&1 &
  pid=$!
  while :; do
    if [ -z "$url" ]; then url=$(grep -o 'http://[^ ]*' serve.out || true); fi
    if [ -n "$url" ] && curl -sf -o /dev/null "${url}api/materials"; then break; fi
    if ! kill -0 "$pid" 2> /dev/null; then echo "btf serve exited: $(cat serve.out)" >&2; exit 1; fi
    sleep 0.01
  done
  t=$(echo "$(now) - $start" | bc -l)
  kill -INT "$pid"
  wait "$pid" || true
  printf '%.2f\n' "$t"
}

echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load average $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# DFMF ${size}² texels, dome151 (151 views × 151 lights), K = $components half floats per channel; best of $runs"
echo
echo "| colour model | file | package | convert | peak memory | serve start, empty cache | serve start, warm cache |"
echo "|---|---|---|---|---|---|---|"
for model in 0 11; do
  file=m$model.btf
  [ -f "$file" ] || "$files" write "$file" --size "$size" --components "$components" --model "$model" 2> /dev/null
  convert_s=() convert_kb=()
  for ((r = 0; r < runs; ++r)); do
    rm -f "m$model.btfpkg"
    read -r s kb < <(timed "$btf" -q convert "$file" "m$model.btfpkg")
    convert_s+=("$s") convert_kb+=("$kb")
  done
  cold=() warm=()
  for ((r = 0; r < runs; ++r)); do
    rm -rf cache
    cold+=("$(serve_start "$file" cache)")
    warm+=("$(serve_start "$file" cache)")
  done
  rm -rf cache
  printf '| %s | %.1f MB | %.1f MB | %s s | %.0f MB | %s s | %s s |\n' "$model" \
    "$(echo "$(stat -c %s "$file") / 1000000" | bc -l)" \
    "$(echo "$(stat -c %s "m$model.btfpkg") / 1000000" | bc -l)" \
    "$(printf '%s\n' "${convert_s[@]}" | best)" \
    "$(echo "$(printf '%s\n' "${convert_kb[@]}" | best) / 1000" | bc -l)" \
    "$(printf '%s\n' "${cold[@]}" | best)" "$(printf '%s\n' "${warm[@]}" | best)"
done

echo
echo "## btf eval of one query (whole process)"
echo
echo "| input | wall time | peak memory |"
echo "|---|---|---|"
for input in m0.btf m0.btfpkg m11.btf m11.btfpkg; do
  ts=() kbs=()
  for ((r = 0; r < runs; ++r)); do
    read -r s kb < <(timed "$btf" eval "$input" --uv 0.3,0.7 --light 33,47 --view 21,200)
    ts+=("$s") kbs+=("$kb")
  done
  printf '| `btf eval %s` | %s s | %.0f MB |\n' "$input" "$(printf '%s\n' "${ts[@]}" | best)" \
    "$(echo "$(printf '%s\n' "${kbs[@]}" | best) / 1000" | bc -l)"
done

for model in 0 11; do
  echo
  echo "## eval() on m$model.btf"
  echo
  "$files" eval "m$model.btf" --repeat "$runs"
done
echo; echo "# load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
