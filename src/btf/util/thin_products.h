// SPDX-License-Identifier: MIT
#pragma once
/// The two products of a randomized factorization's pass, of a wide matrix A (rows as read, row
/// major, n columns) with a thin factor (w ≤ a few hundred columns):
///
///   y  = A · Xᵀ   (rows × w; X is w × n, the factor stored transposed)
///   zt += Qᵀ · A  (w × n;   Q is rows × w)
///
/// On CPUs with AVX-512 they run btfkit's own kernels: X is read as stored, A in place, and
/// neither is packed, so narrow factors keep the rate of wide ones (OpenBLAS's sgemm packs the
/// thin factor again on every call: bench/gemm_pass measures both). Elsewhere they call
/// OpenBLAS (blas::sgemm). Either way a call runs on the calling thread and gives the same bits
/// for the same arguments; callers split their work in chunks fixed by the shapes (as OpenBLAS's
/// sums depend on the chunk's edges). btfkit's kernels go further: every output element is summed
/// in an order fixed by w and n alone, whatever rows of y or columns of zt a call covers.

#include <cstdint>
#include <string_view>

namespace btf::thin {

/// Which implementation runs the products.
enum class Kernel {
    kOwn,   ///< btfkit's AVX-512 kernels (the default where the CPU has AVX-512F)
    kBlas,  ///< OpenBLAS's sgemm (the default elsewhere)
};

/// The implementation in use; "avx512" or "openblas".
Kernel kernel();
std::string_view kernel_name();
/// Chooses the implementation for the whole process (benchmarks and tests compare the two);
/// kOwn where the CPU lacks AVX-512F fails. Not to be called while products run.
void set_kernel(Kernel kernel);
/// True where the CPU can run kOwn.
bool own_kernel_supported();

/// y (rows × w, row stride ldy) = a (rows × n, row stride lda) · xᵀ, x: w × n (row stride ldx).
void multiply(const float* a, int64_t rows, int64_t n, int64_t lda, const float* x, int64_t w,
              int64_t ldx, float* y, int64_t ldy);

/// zt (w × n, row stride ldz) += qᵀ · a, q: rows × w (row stride ldq), a: rows × n (row stride
/// lda).
void multiply_add_transposed(const float* q, int64_t rows, int64_t w, int64_t ldq, const float* a,
                             int64_t n, int64_t lda, float* zt, int64_t ldz);

}  // namespace btf::thin
