// SPDX-License-Identifier: MIT
#include "btf/util/thin_products.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "btf/util/error.h"

namespace btf::thin {
namespace {

// A row-major matrix with a row stride larger than its width; the padding holds a marker that the
// products must leave alone.
struct Strided {
    int64_t rows, cols, stride;
    std::vector<float> data;
    static constexpr float kPadding = -12345.0f;

    Strided(int64_t r, int64_t c, int64_t pad, std::mt19937& rng)
        : rows(r), cols(c), stride(c + pad), data(size_t(r * (c + pad)), kPadding) {
        std::uniform_real_distribution<float> uniform(-1.0f, 1.0f);
        for (int64_t i = 0; i < rows; ++i)
            for (int64_t j = 0; j < cols; ++j) at(i, j) = uniform(rng);
    }
    float& at(int64_t i, int64_t j) { return data[size_t(i * stride + j)]; }
    float at(int64_t i, int64_t j) const { return data[size_t(i * stride + j)]; }
    bool padding_intact() const {
        for (int64_t i = 0; i < rows; ++i)
            for (int64_t j = cols; j < stride; ++j)
                if (at(i, j) != kPadding) return false;
        return true;
    }
};

// Selects a kernel for one test and restores the default afterwards.
class WithKernel {
  public:
    explicit WithKernel(Kernel k) : saved_(kernel()) { set_kernel(k); }
    ~WithKernel() { set_kernel(saved_); }

  private:
    Kernel saved_;
};

std::vector<Kernel> kernels() {
    std::vector<Kernel> out = {Kernel::kBlas};
    if (own_kernel_supported()) out.push_back(Kernel::kOwn);
    return out;
}

const char* name(Kernel k) {
    return k == Kernel::kOwn ? "own" : "blas";
}

// Shapes around the kernels' edges: single rows and columns, widths just under, at and over the
// tile sizes (4 rows × 6 columns for y, 12 rows × 32 columns for zt), several column blocks of X
// (kc = 512 KiB / (4 w) columns), several row blocks of A for zt (256 rows).
struct Shape {
    int64_t rows, n, w;
};
const Shape kShapes[] = {{1, 1, 1},    {1, 17, 5},    {3, 15, 6},     {4, 16, 7},    {5, 33, 12},
                         {7, 47, 13},  {9, 100, 25},  {13, 300, 37},  {2, 9000, 40}, {6, 4099, 74},
                         {300, 70, 3}, {520, 95, 14}, {11, 2500, 150}};

// The largest |got(r, c) − exact| / Σ|terms| over the output, exact = start(r, c) + Σ_k term(r, c,
// k) in double (start: zero without one).
template <typename Term>
double worst_error(const Strided& got, const Strided* start, int64_t terms, Term&& term) {
    double worst = 0;
    for (int64_t r = 0; r < got.rows; ++r)
        for (int64_t c = 0; c < got.cols; ++c) {
            double exact = start ? start->at(r, c) : 0.0, scale = std::abs(exact);
            for (int64_t k = 0; k < terms; ++k) {
                const double t = term(r, c, k);
                exact += t;
                scale += std::abs(t);
            }
            worst = std::max(worst, std::abs(got.at(r, c) - exact) / scale);
        }
    return worst;
}

TEST(ThinProducts, MultiplyMatchesADoubleReferenceAndKeepsThePadding) {
    std::mt19937 rng(7);
    for (const Kernel k : kernels()) {
        const WithKernel use(k);
        for (const Shape& s : kShapes) {
            const Strided a(s.rows, s.n, 3, rng), x(s.w, s.n, 5, rng);
            Strided y(s.rows, s.w, 2, rng);
            multiply(a.data.data(), s.rows, s.n, a.stride, x.data.data(), s.w, x.stride,
                     y.data.data(), y.stride);
            // y(i, p) = Σ_j a(i, j) x(p, j)
            const double worst = worst_error(y, nullptr, s.n, [&](int64_t i, int64_t p, int64_t j) {
                return double(a.at(i, j)) * x.at(p, j);
            });
            EXPECT_LT(worst, 2e-6) << name(k) << " " << s.rows << " × " << s.n << " · " << s.w;
            EXPECT_TRUE(y.padding_intact()) << name(k) << " " << s.rows << " × " << s.n;
        }
    }
}

TEST(ThinProducts, MultiplyAddTransposedAddsToZtAndKeepsThePadding) {
    std::mt19937 rng(8);
    for (const Kernel k : kernels()) {
        const WithKernel use(k);
        for (const Shape& s : kShapes) {
            const Strided q(s.rows, s.w, 3, rng), a(s.rows, s.n, 4, rng);
            Strided zt(s.w, s.n, 6, rng);
            const Strided before = zt;
            multiply_add_transposed(q.data.data(), s.rows, s.w, q.stride, a.data.data(), s.n,
                                    a.stride, zt.data.data(), zt.stride);
            // zt(p, j) = before(p, j) + Σ_i q(i, p) a(i, j)
            const double worst = worst_error(
                zt, &before, s.rows,
                [&](int64_t p, int64_t j, int64_t i) { return double(q.at(i, p)) * a.at(i, j); });
            EXPECT_LT(worst, 2e-6) << name(k) << " " << s.rows << " × " << s.n << " · " << s.w;
            EXPECT_TRUE(zt.padding_intact()) << name(k) << " " << s.rows << " × " << s.n;
        }
    }
}

// btfkit's kernels sum each element in an order fixed by w and n alone: the same bits whatever
// rows of y or columns of zt a call covers. (OpenBLAS's kernels do not promise that: the
// factorization calls them on chunks fixed by the shapes.)
TEST(ThinProducts, OwnKernelsGiveTheSameBitsHoweverTheCallerSplitsTheWork) {
    if (!own_kernel_supported()) GTEST_SKIP() << "no AVX-512F on this CPU";
    std::mt19937 rng(9);
    const int64_t rows = 23, n = 5000, w = 37;
    const Strided a(rows, n, 0, rng), x(w, n, 0, rng), q(rows, w, 0, rng);
    {
        const Kernel k = Kernel::kOwn;
        const WithKernel use(k);
        std::vector<float> whole(size_t(rows * w)), split(size_t(rows * w));
        multiply(a.data.data(), rows, n, n, x.data.data(), w, n, whole.data(), w);
        for (const auto [r0, r1] : {std::pair<int64_t, int64_t>{0, 5}, {5, 6}, {6, 17}, {17, 23}})
            multiply(a.data.data() + r0 * n, r1 - r0, n, n, x.data.data(), w, n,
                     split.data() + r0 * w, w);
        EXPECT_EQ(whole, split) << name(k);

        std::vector<float> zt_whole(size_t(w * n), 0.5f), zt_split(size_t(w * n), 0.5f);
        multiply_add_transposed(q.data.data(), rows, w, w, a.data.data(), n, n, zt_whole.data(), n);
        for (const auto [c0, c1] :
             {std::pair<int64_t, int64_t>{0, 7}, {7, 2048}, {2048, 2081}, {2081, 5000}})
            multiply_add_transposed(q.data.data(), rows, w, w, a.data.data() + c0, c1 - c0, n,
                                    zt_split.data() + c0, n);
        EXPECT_EQ(zt_whole, zt_split) << name(k);
    }
}

TEST(ThinProducts, EmptyShapesLeaveTheOutputAsItWas) {
    for (const Kernel k : kernels()) {
        const WithKernel use(k);
        const std::vector<float> a(8, 1.0f), x(8, 1.0f);
        std::vector<float> zt(8, 3.0f);
        multiply_add_transposed(a.data(), 0, 2, 2, a.data(), 4, 4, zt.data(), 4);
        EXPECT_EQ(zt, std::vector<float>(8, 3.0f)) << name(k);
        std::vector<float> y(4, 3.0f);
        multiply(a.data(), 2, 0, 4, x.data(), 2, 4, y.data(), 2);  // no columns: y = 0
        EXPECT_EQ(y, std::vector<float>(4, 0.0f)) << name(k);
    }
}

TEST(ThinProducts, TheOwnKernelIsRefusedWhereTheCpuCannotRunIt) {
    const Kernel saved = kernel();
    EXPECT_EQ(saved == Kernel::kOwn, own_kernel_supported());
    if (own_kernel_supported()) {
        EXPECT_NO_THROW(set_kernel(Kernel::kOwn));
        EXPECT_EQ(kernel_name(), "avx512");
    } else {
        EXPECT_THROW(set_kernel(Kernel::kOwn), Error);
        EXPECT_EQ(kernel_name(), "openblas");
    }
    set_kernel(saved);
}

}  // namespace
}  // namespace btf::thin
