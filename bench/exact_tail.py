#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The Eckart–Young optimum of a large matrix: the exact relative error of its best rank-C
approximation, for bench/fmf_speed.cpp's --exact (docs/benchmarks.md, issue 22).

Usage: exact_tail.py MATRIX.npy [C ...]

The matrix (float32, C order, m × n with m ≤ n, such as fmf_speed's 19683 × 65536) is loaded
fully. The Gram matrix M Mᵀ is accumulated in double over 4096-column slices, its largest
eigenvalues found by LAPACK (scipy.linalg.eigh, driver evr), and for each C the error
sqrt(1 − Σ_{i ≤ C} λ_i / ‖M‖²_F) is printed. 19683 × 65536 took 15 minutes on 2 cores.
"""

import sys
import time

import numpy as np
import scipy.linalg


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    ranks = [int(c) for c in sys.argv[2:]] or [8, 32, 64]
    matrix = np.load(sys.argv[1])
    m, n = matrix.shape
    if matrix.dtype != np.float32 or m > n:
        sys.exit(f"{sys.argv[1]}: expected a float32 matrix with no more rows than columns")
    start = time.perf_counter()
    total = sum(
        float(np.square(matrix[r : r + 1024], dtype=np.float64).sum()) for r in range(0, m, 1024)
    )
    gram = np.zeros((m, m), np.float64)
    for c in range(0, n, 4096):
        part = matrix[:, c : c + 4096].astype(np.float64)
        gram += part @ part.T
    print(f"Gram matrix {m} × {m}: {time.perf_counter() - start:.0f} s", file=sys.stderr)
    top = max(ranks)
    eigenvalues = scipy.linalg.eigh(
        gram, eigvals_only=True, subset_by_index=[m - top, m - 1], overwrite_a=True, driver="evr"
    )[::-1]
    print(f"eigenvalues: {time.perf_counter() - start:.0f} s", file=sys.stderr)
    print("| C | exact rel. error |\n|---|---|")
    for c in ranks:
        print(f"| {c} | {np.sqrt(max(0.0, 1 - eigenvalues[:c].sum() / total)):.6f} |")


if __name__ == "__main__":
    main()
