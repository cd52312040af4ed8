#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The reference of bench/fmf_speed.cpp: scikit-learn's randomized SVD of the same matrix.

Usage: sklearn_rsvd.py MATRIX.npy OUT_PREFIX COMPONENTS POWER_ITERATIONS OVERSAMPLING

Loads the float32 matrix fully into memory (no memory map), then times only
sklearn.utils.extmath.randomized_svd with the given settings, QR power-iteration normalizer and
random_state=0. Writes OUT_PREFIX.u (rows × k), OUT_PREFIX.s (k), OUT_PREFIX.vt (k × cols) as raw
little-endian float32 in C order, and OUT_PREFIX.json with the timing and memory figures:
seconds, rss_loaded (resident bytes after loading), peak_extra (peak resident bytes during the
call minus rss_loaded), peak (peak resident bytes during the call), threads (BLAS threads).
"""

import json
import sys
import time

import numpy as np
from sklearn.utils.extmath import randomized_svd


def status_bytes(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return 0


def blas_threads():
    try:
        from threadpoolctl import threadpool_info

        return [i.get("num_threads") for i in threadpool_info() if i.get("user_api") == "blas"]
    except ImportError:
        return []


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    path, prefix = sys.argv[1], sys.argv[2]
    components, power_iterations, oversampling = map(int, sys.argv[3:6])
    matrix = np.load(path, mmap_mode=None)
    if matrix.dtype != np.float32:
        sys.exit(f"{path}: dtype {matrix.dtype}, expected float32")
    rss_loaded = status_bytes("VmRSS")
    # Reset the peak to the current resident size so the peak of the call alone is measured.
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    start = time.perf_counter()
    u, s, vt = randomized_svd(
        matrix,
        n_components=components,
        n_oversamples=oversampling,
        n_iter=power_iterations,
        power_iteration_normalizer="QR",
        random_state=0,
    )
    seconds = time.perf_counter() - start
    peak = status_bytes("VmHWM")
    for name, array in (("u", u), ("s", s), ("vt", vt)):
        np.ascontiguousarray(array, dtype="<f4").tofile(f"{prefix}.{name}")
    result = {
        "seconds": seconds,
        "rss_loaded": rss_loaded,
        "peak": peak,
        "peak_extra": peak - rss_loaded,
        "threads": blas_threads(),
        "dtype": str(u.dtype),
        "shape": list(matrix.shape),
    }
    with open(f"{prefix}.json", "w") as f:
        json.dump(result, f)


if __name__ == "__main__":
    main()
