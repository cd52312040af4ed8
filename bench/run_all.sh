#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Runs every benchmark behind docs/benchmarks.md and prints its raw output. Usage:
#   bash bench/run_all.sh [build-dir]        (make bench does this with build/release)
# Timings need a quiet machine: nothing else should run meanwhile.
set -euo pipefail
build=${1:-build/release}
echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
echo; echo "## angular interpolation"; "$build/interp_bench" --benchmark_min_time=1
echo; echo "## UBO2003 import (real view)"; "$build/ubo2003_import_bench" --benchmark_min_time=2
echo; echo "## HDF5 write/read"; "$build/h5_speed"
echo; echo "## synthesis"; "$build/synth_bench"
echo; echo "## synthetic vs. real: rank-k relative RMSE"; "$build/synth_realism"
echo; echo "## codecs: fmf accuracy against the exact SVD"; "$build/fmf_accuracy"
echo; echo "## codecs: fmf compression speed (vs scikit-learn)"; "$build/fmf_speed"
echo; echo "## codecs: evaluation throughput"; "$build/eval_bench"
echo; echo "## codecs: rate–distortion"; "$build/rate_distortion"
echo; echo "## quality: per-image measures throughput"; "$build/quality_bench" --size 128 --threads 2
echo; echo "## quality: BTF-CIELab wall time and memory"; "$build/btf_cielab_bench" --size 256 --grid 5
echo; echo "## quality: perceptual vs fmf at equal size"; bash "$(dirname "$0")/perceptual_vs_fmf.sh" "$build" 16 64 3
echo; echo "## quality: high-frequency omission"; bash "$(dirname "$0")/perceptual_omission.sh" "$build" 32 64 3
echo; echo "## mlvq: code-vector search"; "$build/mlvq_vq_bench" --size 64
echo; echo "## viewer: UBO2014 files as they are"; bash "$(dirname "$0")/ubo2014_bench.sh" "$build"
