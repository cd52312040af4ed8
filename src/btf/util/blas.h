// SPDX-License-Identifier: MIT
#pragma once
/// Single-precision matrix products through OpenBLAS, run on the calling thread.
///
/// btfkit parallelizes its large products itself, over fixed chunks on its own worker threads,
/// so that results do not depend on the number of threads. OpenBLAS, left to its own threads,
/// splits a product differently for one thread than for two and gives different bits, so its
/// calls must each run on one thread: while a SerialBlas object lives, OpenBLAS runs every call
/// on the calling thread (openblas_set_num_threads(1), restored when the last one ends). The
/// setting is process-wide in OpenBLAS 0.3.21 (per-call control came in 0.3.27), so other users
/// of OpenBLAS in the process (NumPy in the Python module) run single-threaded meanwhile.

#include <cstdint>
#include <string>

namespace btf::blas {

/// The OpenBLAS kernel that runs on this machine ("Cooperlake", "Haswell", …), its version and
/// threading, and OPENBLAS_CORETYPE if set, e.g.
/// "OpenBLAS 0.3.21 DYNAMIC_ARCH NO_AFFINITY Cooperlake MAX_THREADS=64, kernel Cooperlake".
std::string description();
/// The kernel alone ("Cooperlake").
std::string kernel();

class SerialBlas {
  public:
    SerialBlas();
    ~SerialBlas();
    SerialBlas(const SerialBlas&) = delete;
    SerialBlas& operator=(const SerialBlas&) = delete;
};

/// c = op(a) · op(b) + beta · c for row-major matrices, op(x) = xᵀ where `transpose_x`:
/// op(a) is m × k, op(b) is k × n, c is m × n; lda, ldb, ldc are row strides in floats. Runs on
/// the calling thread when a SerialBlas lives.
void sgemm(bool transpose_a, bool transpose_b, int64_t m, int64_t n, int64_t k, const float* a,
           int64_t lda, const float* b, int64_t ldb, float beta, float* c, int64_t ldc);

}  // namespace btf::blas
