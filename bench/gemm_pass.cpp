// SPDX-License-Identifier: MIT
// The products of one randomized-SVD pass at the shapes fmf streams (issue 22, groundwork): a
// batch A of b rows × 65536 texel columns times the thin sketch, Y = A·X (X: 65536 × l) and
// Z = Aᵀ·Q (Q: b × l), l = 74 (C = 64 + oversampling 10), float32. Three ways:
//   eigen-chunks   what factor/rsvd.cpp does: Eigen products over fixed chunks on TBB's threads
//                  (64-row chunks for Y, 2048-column slices for Z);
//   openblas       one cblas_sgemm per batch on OpenBLAS's own threads;
//   openblas-1t    one single-threaded sgemm per fixed chunk on TBB's threads (the chunks of
//                  eigen-chunks), so that no sum depends on the number of threads;
//   openblas-1t-zt the same with the transposed product as Zᵀ = Qᵀ·A;
//   btfkit         what factor/rsvd.cpp does now: btfkit's thin-product kernels
//                  (util/thin_products.h; AVX-512, or OpenBLAS where the CPU has none) on
//                  TBB's threads, 128-row chunks for Y = A·X (X held transposed), 2048-column
//                  slices for Zᵀ = Qᵀ·A.
// For each, the best of --repeat runs in GFLOP/s, and whether the result is bitwise the same with
// one thread as with all (the factorization's guarantee). Prints the OpenBLAS kernel in use
// (OPENBLAS_CORETYPE, when set, chooses it), the rate of a square 4096² sgemm on OpenBLAS's
// threads for reference, and a Markdown table.
//
//   build/<dir>/gemm_pass [--repeat 5] [--rows 243,972,2916,8192]

#include <cblas.h>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "btf/util/parallel.h"
#include "btf/util/thin_products.h"

extern "C" char* openblas_get_corename(void);
extern "C" int openblas_get_num_threads(void);
extern "C" void openblas_set_num_threads(int threads);

namespace {

using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
constexpr int64_t kCols = 65536;
int64_t kRowChunk = 64, kColumnSlice = 2048;
const Matrix* transposed_x = nullptr;  // Xᵀ, for the btfkit way

double seconds(const std::function<void()>& run, int repeat) {
    double best = 1e300;
    for (int i = 0; i < repeat; ++i) {
        const auto start = std::chrono::steady_clock::now();
        run();
        best = std::min(
            best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    return best;
}

void sgemm(bool transpose_a, int64_t m, int64_t n, int64_t k, const float* a, int64_t lda,
           const float* b, int64_t ldb, float beta, float* c, int64_t ldc) {
    cblas_sgemm(CblasRowMajor, transpose_a ? CblasTrans : CblasNoTrans, CblasNoTrans, int(m),
                int(n), int(k), 1.0f, a, int(lda), b, int(ldb), beta, c, int(ldc));
}

// y = a·x as one single-threaded sgemm per fixed row chunk on TBB's threads.
void rows_single_threaded(const Matrix& a, const Matrix& x, Matrix& y) {
    btf::parallel_chunks(0, a.rows(), kRowChunk, [&](int64_t r0, int64_t r1) {
        sgemm(false, r1 - r0, x.cols(), a.cols(), a.data() + r0 * a.cols(), a.cols(), x.data(),
              x.cols(), 0, y.data() + r0 * y.cols(), y.cols());
    });
}

struct Way {
    const char* name;
    std::function<void(const Matrix& a, const Matrix& x, Matrix& y)> rows;        // y = a·x
    std::function<void(const Matrix& a, const Matrix& q, Matrix& z)> transposed;  // z = aᵀ·q
    bool blas_threads;  // runs on OpenBLAS's threads (else TBB's, OpenBLAS set to one)
};

std::vector<Way> ways() {
    return {
        {"eigen-chunks",
         [](const Matrix& a, const Matrix& x, Matrix& y) {
             btf::parallel_chunks(0, a.rows(), kRowChunk, [&](int64_t r0, int64_t r1) {
                 y.middleRows(r0, r1 - r0).noalias() = a.middleRows(r0, r1 - r0) * x;
             });
         },
         [](const Matrix& a, const Matrix& q, Matrix& z) {
             btf::parallel_chunks(0, a.cols(), kColumnSlice, [&](int64_t c0, int64_t c1) {
                 z.middleRows(c0, c1 - c0).noalias() = a.middleCols(c0, c1 - c0).transpose() * q;
             });
         },
         false},
        {"openblas",
         [](const Matrix& a, const Matrix& x, Matrix& y) {
             sgemm(false, a.rows(), x.cols(), a.cols(), a.data(), a.cols(), x.data(), x.cols(), 0,
                   y.data(), y.cols());
         },
         [](const Matrix& a, const Matrix& q, Matrix& z) {
             sgemm(true, a.cols(), q.cols(), a.rows(), a.data(), a.cols(), q.data(), q.cols(), 0,
                   z.data(), z.cols());
         },
         true},
        {"openblas-1t", rows_single_threaded,
         [](const Matrix& a, const Matrix& q, Matrix& z) {
             btf::parallel_chunks(0, a.cols(), kColumnSlice, [&](int64_t c0, int64_t c1) {
                 sgemm(true, c1 - c0, q.cols(), a.rows(), a.data() + c0, a.cols(), q.data(),
                       q.cols(), 0, z.data() + c0 * z.cols(), z.cols());
             });
         },
         false},
        {"openblas-1t-zt",  // the transposed product as Zᵀ = Qᵀ·A (z's storage holds Zᵀ)
         rows_single_threaded,
         [](const Matrix& a, const Matrix& q, Matrix& z) {
             btf::parallel_chunks(0, a.cols(), kColumnSlice, [&](int64_t c0, int64_t c1) {
                 sgemm(true, q.cols(), c1 - c0, a.rows(), q.data(), q.cols(), a.data() + c0,
                       a.cols(), 0, z.data() + c0, a.cols());
             });
         },
         false},
        {"btfkit",
         [](const Matrix& a, const Matrix& x, Matrix& y) {
             btf::parallel_chunks(0, a.rows(), 128, [&](int64_t r0, int64_t r1) {
                 btf::thin::multiply(a.data() + r0 * a.cols(), r1 - r0, a.cols(), a.cols(),
                                     transposed_x->data(), x.cols(), a.cols(),
                                     y.data() + r0 * y.cols(), y.cols());
             });
         },
         [](const Matrix& a, const Matrix& q, Matrix& z) {
             z.setZero();
             btf::parallel_chunks(0, a.cols(), 2048, [&](int64_t c0, int64_t c1) {
                 btf::thin::multiply_add_transposed(q.data(), a.rows(), q.cols(), q.cols(),
                                                    a.data() + c0, c1 - c0, a.cols(), z.data() + c0,
                                                    a.cols());
             });
         },
         false},
    };
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app("GEMM rates of a randomized-SVD pass at fmf's shapes");
    int repeat = 5;
    std::vector<int64_t> batch_rows = {243, 972, 2916, 8192};
    app.add_option("--repeat", repeat, "runs; the best counts")->check(CLI::Range(1, 100));
    app.add_option("--rows", batch_rows, "rows per batch (243: one view of 81 lights × RGB)")
        ->delimiter(',');
    int64_t width = 74;
    app.add_option("--width", width, "columns of the thin factor (74: C = 64 + oversampling 10)")
        ->capture_default_str();
    app.add_option("--row-chunk", kRowChunk, "rows per chunk of the direct products")
        ->capture_default_str();
    app.add_option("--column-slice", kColumnSlice, "columns per slice of the transposed products")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    const int64_t kWidth = width;

    const int all = openblas_get_num_threads();
    const char* coretype = std::getenv("OPENBLAS_CORETYPE");
    std::printf(
        "OpenBLAS kernel %s (OPENBLAS_CORETYPE %s), %d threads; btfkit's thin products: %s; %lld "
        "columns, l = %lld\n\n",
        openblas_get_corename(), coretype ? coretype : "unset", all,
        std::string(btf::thin::kernel_name()).c_str(), static_cast<long long>(kCols),
        static_cast<long long>(kWidth));
    {
        // The machine's GEMM rate for reference: a square product on OpenBLAS's own threads.
        const int64_t n = 4096;
        const Matrix a = Matrix::Random(n, n), b = Matrix::Random(n, n);
        Matrix c(n, n);
        openblas_set_num_threads(all);
        const double t = seconds(
            [&] { sgemm(false, n, n, n, a.data(), n, b.data(), n, 0, c.data(), n); }, repeat);
        std::printf("square %lld² sgemm on OpenBLAS's %d threads: %.0f GFLOP/s\n\n",
                    static_cast<long long>(n), all,
                    2.0 * double(n) * double(n) * double(n) / t / 1e9);
    }
    std::printf(
        "| rows per batch | way | Y = A·X (GFLOP/s) | Z = Aᵀ·Q (GFLOP/s) | same with 1 thread |\n");
    std::printf("|---|---|---|---|---|\n");
    for (const int64_t rows : batch_rows) {
        const Matrix a = Matrix::Random(rows, kCols), x = Matrix::Random(kCols, kWidth),
                     q = Matrix::Random(rows, kWidth);
        const Matrix xt = x.transpose();
        transposed_x = &xt;
        const double flop = 2.0 * double(rows) * double(kCols) * double(kWidth);
        for (const Way& way : ways()) {
            openblas_set_num_threads(way.blas_threads ? all : 1);
            Matrix y(rows, kWidth), z(kCols, kWidth);
            const double ty = seconds([&] { way.rows(a, x, y); }, repeat);
            const double tz = seconds([&] { way.transposed(a, q, z); }, repeat);
            Matrix y1(rows, kWidth), z1(kCols, kWidth);
            {
                btf::ThreadLimit one(1);
                if (way.blas_threads) openblas_set_num_threads(1);
                way.rows(a, x, y1);
                way.transposed(a, q, z1);
            }
            const bool same = y1 == y && z1 == z;
            std::printf("| %lld | %s | %.0f | %.0f | %s |\n", static_cast<long long>(rows),
                        way.name, flop / ty / 1e9, flop / tz / 1e9, same ? "yes" : "**no**");
            std::fflush(stdout);
        }
    }
    openblas_set_num_threads(all);
    return 0;
}
