#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# How long `btf` takes to stop after SIGTERM, at several stages of real work: the time from the
# signal to the process's exit, its exit code, and whether anything was left in the output folder.
# Usage: bench/cancel_latency.sh [path/to/btf]   (prints a Markdown table for docs/reliability.md)
set -euo pipefail
btf="$(realpath "${1:-build/release/btf}")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"

"$btf" --quiet synth --preset woven_fabric --size 256 -o src.h5
# Runs "$@" (stderr to a log), waits until the log matches $ready (or, when $ready is empty, 1 s
# after the process can take the signal: quiet runs print nothing), sends SIGTERM, and prints
# "| stage | ms from signal to exit | exit code | files left |".
measure() {
    local stage="$1" ready="$2"
    shift 2
    mkdir -p out
    "$@" 2> log &
    local pid=$!
    if [ -z "$ready" ]; then
        # Until btf has installed its SIGTERM handler (bit 15 of SigCgt), then 1 s of work.
        until [ $(( 0x$(awk '/^SigCgt/ {print $2}' /proc/$pid/status) & 0x4000 )) -ne 0 ]; do
            sleep 0.01
        done
        sleep 1
    else
        until grep -q -- "$ready" log 2> /dev/null; do sleep 0.01; done
    fi
    local t0 t1 code=0
    t0=$(date +%s%N)
    kill -TERM "$pid"
    wait "$pid" || code=$?
    t1=$(date +%s%N)
    echo "| $stage | $(( (t1 - t0) / 1000000 )) | $code | $(ls -A out | wc -l) |"
    rm -rf out log
}

echo "| stage (btf on a 256² × 81 × 81 material) | ms from SIGTERM to exit | exit code | files left |"
echo "|---|---|---|---|"
measure "synth: computing and writing images" "" "$btf" --quiet synth --preset leather --size 256 -o out/x.h5
measure "compress: reading the source" "reading\|factorizing: pass 1" "$btf" compress src.h5 -o out/x.btfpkg --codec fmf -p components=16
measure "compress: factorizing (pass 3)" "factorizing: pass 3" "$btf" compress src.h5 -o out/x.btfpkg --codec fmf -p components=16
measure "compress: measuring the error" "measuring error" "$btf" compress src.h5 -o out/x.btfpkg --codec fmf -p components=16
measure "compress mlvq: training" "" "$btf" compress src.h5 -o out/x.btfpkg --codec mlvq
measure "convert: decoding and writing PNGs" "" "$btf" convert src.h5 out/utia
