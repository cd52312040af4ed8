// SPDX-License-Identifier: MIT
#include "btf/codecs/perceptual/csf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "btf/core/math.h"
#include "btf/testing/sources.h"
#include "btf/util/parallel.h"

namespace btf::perceptual {
namespace {

using factor::Matrix;

Matrix random_matrix(int64_t rows, int64_t cols, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<float> normal;
    Matrix m(rows, cols);
    for (int64_t i = 0; i < m.size(); ++i) m.data()[i] = normal(rng);
    return m;
}

double sum_of(const std::vector<Gaussian>& mixture) {
    double s = 0;
    for (const Gaussian& g : mixture) s += g.weight;
    return s;
}

TEST(Csf, EveryMixtureOfTable2HasUnitDcGain) {
    for (const Csf* csf : {&achromatic_csf(), &chromatic_csf()}) {
        EXPECT_NEAR(sum_of(csf->spatial), 1.0, 1e-4);
        EXPECT_NEAR(sum_of(csf->angular), 1.0, 1e-4);
    }
    EXPECT_EQ(achromatic_csf().spatial.size(), 3u);
    EXPECT_EQ(chromatic_csf().angular.size(), 2u);
    EXPECT_DOUBLE_EQ(achromatic_csf().angular[1].sigma, 0.137456);
}

// One Gaussian of σ = 0.3° at 10 texels per degree is 3 texels wide: its impulse response is
// exp(−r²/9) / (9π), the unit-integral form of exp(−x²/σ²).
TEST(Csf, SpatialFilterIsTheUnitIntegralGaussianInTexels) {
    const int n = 32;
    const SpatialFilter filter({{1.0, 0.3}}, 10.0, n, n);
    Matrix impulse = Matrix::Zero(n * n, 1);
    impulse(0, 0) = 1;
    filter.apply(impulse);
    double total = 0;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const int dx = std::min(x, n - x), dy = std::min(y, n - y);  // periodic distance
            const double expected = std::exp(-(dx * dx + dy * dy) / 9.0) / (9.0 * kPi);
            EXPECT_NEAR(impulse(y * n + x, 0), expected, 2e-6) << x << ", " << y;
            total += impulse(y * n + x, 0);
        }
    EXPECT_NEAR(total, 1.0, 1e-5);
}

TEST(Csf, SpatialFilterIsSymmetricKeepsConstantsAndFiltersColumnsIndependently) {
    const int w = 12, h = 10;  // neither square nor a power of two
    const SpatialFilter filter(achromatic_csf().spatial, 10.0, w, h);
    const Matrix x = random_matrix(w * h, 3, 1), y = random_matrix(w * h, 3, 2);
    Matrix tx = x, ty = y;
    filter.apply(tx);
    filter.apply(ty);
    for (int c = 0; c < 3; ++c) {
        const double a = x.col(c).cast<double>().dot(ty.col(c).cast<double>());
        const double b = tx.col(c).cast<double>().dot(y.col(c).cast<double>());
        EXPECT_NEAR(a, b, 1e-4 * std::abs(a) + 1e-4);
        // Pairs share one complex FFT: a column alone gives the same result.
        Matrix one = x.col(c);
        filter.apply(one);
        for (int t = 0; t < w * h; ++t) EXPECT_NEAR(one(t, 0), tx(t, c), 1e-5);
    }
    EXPECT_GT((tx - x).norm(), 0.1 * x.norm());  // it does filter
    Matrix constant = Matrix::Constant(w * h, 1, 2.5f);
    filter.apply(constant);
    for (int t = 0; t < w * h; ++t) EXPECT_NEAR(constant(t, 0), 2.5f, 1e-5);
}

TEST(Csf, SpatialFilterIsDeterministicForAnyThreadCount) {
    const SpatialFilter filter(chromatic_csf().spatial, 20.0, 16, 16);
    Matrix one = random_matrix(256, 9, 3), two = one;
    {
        ThreadLimit limit(1);
        filter.apply(one);
    }
    {
        ThreadLimit limit(2);
        filter.apply(two);
    }
    EXPECT_EQ(one, two);
}

TEST(Csf, AngularKernelRowsAreNormalizedGaussiansOfTheGreatCircleAngle) {
    const DirectionSet& set = test::ubo_subset(10, 12).views;
    const Eigen::MatrixXd k = angular_kernel(set, 20.0);
    for (int i = 0; i < set.size(); ++i) {
        EXPECT_NEAR(k.row(i).sum(), 1.0, 1e-12);
        for (int j = 0; j < set.size(); ++j) {
            const double angle =
                degrees(std::acos(std::clamp(dot(set.vector(i), set.vector(j)), -1.0, 1.0)));
            EXPECT_NEAR(k(i, j) / k(i, i), std::exp(-(angle / 20.0) * (angle / 20.0)), 1e-6);
        }
    }
}

TEST(Csf, AngularFilterIsTheMixtureOfKroneckerProducts) {
    const Sampling s = test::ubo_subset(5, 4);
    const AngularFilter filter(achromatic_csf().angular, 300.0, s);
    const Eigen::MatrixXd t = filter.matrix();
    ASSERT_EQ(t.rows(), 20);
    for (int r = 0; r < 20; ++r) EXPECT_NEAR(t.row(r).sum(), 1.0, 1e-4);  // Σ w = 1
    EXPECT_GT((t - t.transpose()).norm(), 1e-3);  // row normalization breaks symmetry
    // Against the definition, one entry: Σ_i w_i K_view,i(v, w) K_light,i(l, m).
    double expected = 0;
    for (const Gaussian& g : achromatic_csf().angular)
        expected += g.weight * angular_kernel(s.views, g.sigma * 300.0)(1, 3) *
                    angular_kernel(s.lights, g.sigma * 300.0)(2, 0);
    EXPECT_NEAR(t(1 * 4 + 2, 3 * 4 + 0), expected, 1e-6);
    for (const bool transpose : {false, true}) {
        Matrix y = random_matrix(20, 5, 4);
        const Eigen::MatrixXd want =
            (transpose ? Eigen::MatrixXd(t.transpose()) : t) * y.cast<double>();
        filter.apply(y, transpose);
        EXPECT_LT((y.cast<double>() - want).norm(), 1e-5 * want.norm()) << transpose;
    }
}

TEST(Csf, SlowMotionMakesTheAngularFilterTheIdentity) {
    const Sampling s = test::ubo_subset(6, 5);
    // 1 °/s: the widest Gaussian is 0.16° wide, far below the directions' spacing.
    const Eigen::MatrixXd t = AngularFilter(chromatic_csf().angular, 1.0, s).matrix();
    EXPECT_LT((t - Eigen::MatrixXd::Identity(30, 30)).norm(), 1e-9);
}

TEST(Csf, TransformsFilterEachPlaneWithItsCsf) {
    const Sampling s = test::ubo_subset(3, 4);
    const CsfTransforms transforms(s, 8, 8, {10, 100});
    const Matrix x = random_matrix(64, 2, 5);
    Matrix l = x, a = x, chroma = x;
    transforms.right(0, l, false);
    transforms.right(1, a, false);
    SpatialFilter(chromatic_csf().spatial, 10, 8, 8).apply(chroma);
    EXPECT_EQ(a, chroma);
    EXPECT_GT((l - a).norm(), 1e-3 * l.norm());
    Matrix y = random_matrix(12, 2, 6), z = y;
    transforms.left(2, y, true);
    AngularFilter(chromatic_csf().angular, 100, s).apply(z, true);
    EXPECT_EQ(y, z);
}

}  // namespace
}  // namespace btf::perceptual
