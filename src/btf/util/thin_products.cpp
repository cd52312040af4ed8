// SPDX-License-Identifier: MIT
#include "btf/util/thin_products.h"

#include <immintrin.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <utility>

#include "btf/util/blas.h"
#include "btf/util/error.h"

// The kernels are compiled for AVX-512F by function attribute, not by flags for the whole file,
// so that nothing else here (nor any inline function of a header) needs the instructions; they
// run only after own_kernel_supported() said yes.
#define BTF_AVX512 __attribute__((target("avx512f")))

namespace btf::thin {

namespace {

// ---- y = A · Xᵀ ----------------------------------------------------------------------------
// Output elements in tiles of R rows × P columns (R ≤ 4, P ≤ 6: 24 accumulators of 16 floats,
// 6 registers for X, one for A), each a dot product along A's rows, 16 columns at a time, both
// operands read as stored. The columns go in blocks of kc so that the block of X (w × kc) stays
// in the L2 cache while the rows pass; each tile's 16 partial sums are reduced at the end of a
// block and added to y. The order of every sum depends on w and n alone.
constexpr int kDotRows = 4;
constexpr int kDotCols = 6;
constexpr int64_t kXBlockBytes = 512 << 10;

// Σ of the 16 lanes, in a fixed order. (The intrinsics _mm512_reduce_add_ps, _mm512_shuffle_f32x4
// and _mm512_permute_ps build on undefined registers that GCC 12 warns about; their zero-masking
// forms with every lane selected are the same instructions.)
BTF_AVX512 inline float lane_sum(__m512 v) {
    constexpr __mmask16 all = 0xFFFF;
    v = _mm512_add_ps(v, _mm512_maskz_shuffle_f32x4(all, v, v, _MM_SHUFFLE(1, 0, 3, 2)));
    v = _mm512_add_ps(v, _mm512_maskz_shuffle_f32x4(all, v, v, _MM_SHUFFLE(2, 3, 0, 1)));
    v = _mm512_add_ps(v, _mm512_maskz_permute_ps(all, v, _MM_SHUFFLE(1, 0, 3, 2)));
    v = _mm512_add_ps(v, _mm512_maskz_permute_ps(all, v, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm512_cvtss_f32(v);
}

// Keeps a loaded vector in its register: without it GCC folds the load into every FMA that uses
// the vector, loading each element of X once per row of A instead of once.
BTF_AVX512 inline void keep_in_register(__m512& v) {
    asm("" : "+v"(v));
}

template <int R, int P>
BTF_AVX512 void dot_tile(const float* a, int64_t lda, const float* x, int64_t ldx, int64_t n,
                         float* y, int64_t ldy) {
    __m512 acc[R][P];
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r)
#pragma GCC unroll 6
        for (int p = 0; p < P; ++p) acc[r][p] = _mm512_setzero_ps();
    int64_t k = 0;
    for (; k + 16 <= n; k += 16) {
        __m512 xv[P];
#pragma GCC unroll 6
        for (int p = 0; p < P; ++p) {
            xv[p] = _mm512_loadu_ps(x + p * ldx + k);
            keep_in_register(xv[p]);
        }
#pragma GCC unroll 4
        for (int r = 0; r < R; ++r) {
            const __m512 av = _mm512_loadu_ps(a + r * lda + k);
#pragma GCC unroll 6
            for (int p = 0; p < P; ++p) acc[r][p] = _mm512_fmadd_ps(av, xv[p], acc[r][p]);
        }
    }
    if (k < n) {
        const __mmask16 mask = static_cast<__mmask16>((1u << (n - k)) - 1);
        __m512 xv[P];
#pragma GCC unroll 6
        for (int p = 0; p < P; ++p) xv[p] = _mm512_maskz_loadu_ps(mask, x + p * ldx + k);
#pragma GCC unroll 4
        for (int r = 0; r < R; ++r) {
            const __m512 av = _mm512_maskz_loadu_ps(mask, a + r * lda + k);
#pragma GCC unroll 6
            for (int p = 0; p < P; ++p) acc[r][p] = _mm512_fmadd_ps(av, xv[p], acc[r][p]);
        }
    }
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r)
#pragma GCC unroll 6
        for (int p = 0; p < P; ++p) y[r * ldy + p] += lane_sum(acc[r][p]);
}

using DotTile = void (*)(const float*, int64_t, const float*, int64_t, int64_t, float*, int64_t);

template <int R, int... P>
constexpr std::array<DotTile, sizeof...(P)> dot_row(std::integer_sequence<int, P...>) {
    return {&dot_tile<R, P + 1>...};
}

template <int... R>
constexpr std::array<std::array<DotTile, kDotCols>, sizeof...(R)> dot_table(
    std::integer_sequence<int, R...>) {
    return {dot_row<R + 1>(std::make_integer_sequence<int, kDotCols>{})...};
}

constexpr auto kDotTiles = dot_table(std::make_integer_sequence<int, kDotRows>{});

// Splits `count` into ⌈count / most⌉ parts of nearly equal size (each ≤ most), so that no tile
// is left with a sliver; calls fn(first, size) in order.
template <typename Fn>
void balanced_parts(int64_t count, int64_t most, Fn&& fn) {
    const int64_t parts = (count + most - 1) / most;
    for (int64_t i = 0, first = 0; i < parts; ++i) {
        const int64_t size = (count - first) / (parts - i);
        fn(first, size);
        first += size;
    }
}

BTF_AVX512 void multiply_own(const float* a, int64_t rows, int64_t n, int64_t lda, const float* x,
                             int64_t w, int64_t ldx, float* y, int64_t ldy) {
    for (int64_t r = 0; r < rows; ++r) std::fill(y + r * ldy, y + r * ldy + w, 0.0f);
    const int64_t kc = std::max<int64_t>(256, kXBlockBytes / (4 * w) / 16 * 16);
    for (int64_t k0 = 0; k0 < n; k0 += kc) {
        const int64_t k1 = std::min(n, k0 + kc);
        for (int64_t r0 = 0; r0 < rows; r0 += kDotRows) {
            const int64_t r = std::min<int64_t>(kDotRows, rows - r0);
            balanced_parts(w, kDotCols, [&](int64_t p0, int64_t p) {
                kDotTiles[r - 1][p - 1](a + r0 * lda + k0, lda, x + p0 * ldx + k0, ldx, k1 - k0,
                                        y + r0 * ldy + p0, ldy);
            });
        }
    }
}

// ---- zt += Qᵀ · A ---------------------------------------------------------------------------
// Output elements in tiles of P rows of zt × 32 columns (P ≤ 12: 24 accumulators, two registers
// for A, one for a broadcast element of Q), summed over a block of rows of A and then added to
// zt. Rows go in blocks of kRowBlock so that a tile's strip of A (kRowBlock × 32 floats) stays in
// the L1 cache while the tiles of the other rows of zt pass over it; the next strip is prefetched
// meanwhile (its rows lie a row of A apart: too many streams for the hardware prefetcher).
// (Tiles of 8 × 48 measured the same, bench/gemm_pass.)
constexpr int kOuterRows = 12;
constexpr int kOuterVectors = 2;
constexpr int64_t kRowBlock = 256;

template <int P, int V>
BTF_AVX512 void outer_tile(const float* q, int64_t ldq, int64_t rows, const float* a, int64_t lda,
                           const __mmask16* mask, float* zt, int64_t ldz) {
    __m512 acc[P][V];
#pragma GCC unroll 12
    for (int p = 0; p < P; ++p)
#pragma GCC unroll 3
        for (int v = 0; v < V; ++v) acc[p][v] = _mm512_setzero_ps();
    for (int64_t r = 0; r < rows; ++r) {
        const float* ar = a + r * lda;
#pragma GCC unroll 3
        for (int v = 0; v < V; ++v)
            _mm_prefetch(reinterpret_cast<const char*>(ar + 16 * (V + v)), _MM_HINT_T0);
        __m512 av[V];
#pragma GCC unroll 3
        for (int v = 0; v < V; ++v) {
            av[v] = _mm512_maskz_loadu_ps(mask[v], ar + 16 * v);
            keep_in_register(av[v]);
        }
        const float* qr = q + r * ldq;
#pragma GCC unroll 12
        for (int p = 0; p < P; ++p) {
            const __m512 b = _mm512_set1_ps(qr[p]);
#pragma GCC unroll 3
            for (int v = 0; v < V; ++v) acc[p][v] = _mm512_fmadd_ps(b, av[v], acc[p][v]);
        }
    }
#pragma GCC unroll 12
    for (int p = 0; p < P; ++p) {
        float* out = zt + p * ldz;
#pragma GCC unroll 3
        for (int v = 0; v < V; ++v)
            _mm512_mask_storeu_ps(
                out + 16 * v, mask[v],
                _mm512_add_ps(_mm512_maskz_loadu_ps(mask[v], out + 16 * v), acc[p][v]));
    }
}

using OuterTile = void (*)(const float*, int64_t, int64_t, const float*, int64_t, const __mmask16*,
                           float*, int64_t);

template <int V, int... P>
constexpr std::array<OuterTile, sizeof...(P)> outer_table(std::integer_sequence<int, P...>) {
    return {&outer_tile<P + 1, V>...};
}

constexpr auto kOuterTiles =
    outer_table<kOuterVectors>(std::make_integer_sequence<int, kOuterRows>{});

__mmask16 first_lanes(int64_t count) {
    return count >= 16  ? __mmask16(0xFFFF)
           : count <= 0 ? __mmask16(0)
                        : __mmask16((1u << count) - 1);
}

BTF_AVX512 void multiply_add_transposed_own(const float* q, int64_t rows, int64_t w, int64_t ldq,
                                            const float* a, int64_t n, int64_t lda, float* zt,
                                            int64_t ldz) {
    constexpr int V = kOuterVectors;
    for (int64_t r0 = 0; r0 < rows; r0 += kRowBlock) {
        const int64_t rb = std::min(kRowBlock, rows - r0);
        for (int64_t c0 = 0; c0 < n; c0 += 16 * V) {
            __mmask16 mask[V];
            for (int v = 0; v < V; ++v) mask[v] = first_lanes(n - c0 - 16 * v);
            balanced_parts(w, kOuterRows, [&](int64_t p0, int64_t p) {
                kOuterTiles[p - 1](q + r0 * ldq + p0, ldq, rb, a + r0 * lda + c0, lda, mask,
                                   zt + p0 * ldz + c0, ldz);
            });
        }
    }
}

}  // namespace

bool own_kernel_supported() {
    static const bool supported = [] {
        __builtin_cpu_init();
        return bool(__builtin_cpu_supports("avx512f"));
    }();
    return supported;
}

namespace {

std::atomic<Kernel>& chosen() {
    static std::atomic<Kernel> kernel{own_kernel_supported() ? Kernel::kOwn : Kernel::kBlas};
    return kernel;
}

}  // namespace

Kernel kernel() {
    return chosen().load(std::memory_order_relaxed);
}

std::string_view kernel_name() {
    return kernel() == Kernel::kOwn ? "avx512" : "openblas";
}

void set_kernel(Kernel k) {
    if (k == Kernel::kOwn && !own_kernel_supported())
        fail("thin products: this CPU has no AVX-512F for btfkit's own kernels");
    chosen().store(k, std::memory_order_relaxed);
}

void multiply(const float* a, int64_t rows, int64_t n, int64_t lda, const float* x, int64_t w,
              int64_t ldx, float* y, int64_t ldy) {
    if (rows == 0 || w == 0) return;
    if (kernel() == Kernel::kOwn) return multiply_own(a, rows, n, lda, x, w, ldx, y, ldy);
    blas::sgemm(false, true, rows, w, n, a, lda, x, ldx, 0.0f, y, ldy);
}

void multiply_add_transposed(const float* q, int64_t rows, int64_t w, int64_t ldq, const float* a,
                             int64_t n, int64_t lda, float* zt, int64_t ldz) {
    if (rows == 0 || w == 0 || n == 0) return;
    if (kernel() == Kernel::kOwn)
        return multiply_add_transposed_own(q, rows, w, ldq, a, n, lda, zt, ldz);
    blas::sgemm(true, false, w, n, rows, q, ldq, a, lda, 1.0f, zt, ldz);
}

}  // namespace btf::thin

#undef BTF_AVX512
