// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/angular_levels.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "btf/core/angular_interpolator.h"
#include "btf/testing/support.h"

namespace btf::factor {
namespace {

double angle(const Vec3& a, const Vec3& b) {
    return std::acos(std::clamp(dot(a, b), -1.0, 1.0));
}

// The smallest angle from direction i to the first `count` of `order`.
double distance_to(const DirectionSet& set, const std::vector<int>& order, size_t count, int i) {
    double best = INFINITY;
    for (size_t k = 0; k < count; ++k)
        best = std::min(best, angle(set.vector(i), set.vector(order[k])));
    return best;
}

TEST(AngularLevels, FarthestPointOrderStartsAtThePoleAndTakesTheFarthestNext) {
    const DirectionSet& set = DirectionSet::ubo81();
    const std::vector<int> order = farthest_point_order(set);
    ASSERT_EQ(order.size(), 81u);
    std::vector<int> sorted = order;
    std::sort(sorted.begin(), sorted.end());
    for (int i = 0; i < 81; ++i) ASSERT_EQ(sorted[i], i);  // a permutation
    EXPECT_EQ(order[0], 0);                                // θ = 0 comes first in ubo81
    for (size_t k = 1; k < order.size(); ++k) {
        // Every direction not yet chosen is at most as far from the chosen ones as order[k].
        const double chosen = distance_to(set, order, k, order[k]);
        for (size_t j = k + 1; j < order.size(); ++j)
            ASSERT_LE(distance_to(set, order, k, order[j]), chosen + 1e-12) << k << " " << j;
    }
    // The second direction lies on the outermost ring (75°), as far from the pole as possible.
    EXPECT_NEAR(set[order[1]].theta, radians(75), 1e-9);
}

TEST(AngularLevels, NestedLevelsHalveTheSetsUntilTooFewRemain) {
    const Sampling sampling{DirectionSet::ubo81(), DirectionSet::ubo81()};
    const std::vector<AngularLevel> levels = nested_angular_levels(sampling, 8);
    // 81 → 41, 21, 11, 6, 3; ⌈81/64⌉ = 2 is too few.
    ASSERT_EQ(levels.size(), 5u);
    const size_t sizes[] = {41, 21, 11, 6, 3};
    for (size_t j = 0; j < levels.size(); ++j) {
        EXPECT_EQ(levels[j].views.size(), sizes[j]);
        EXPECT_EQ(levels[j].lights, levels[j].views);
        EXPECT_TRUE(std::is_sorted(levels[j].views.begin(), levels[j].views.end()));
        if (j > 0)  // nested: each level's directions are in the one before
            for (int v : levels[j].views)
                EXPECT_TRUE(
                    std::binary_search(levels[j - 1].views.begin(), levels[j - 1].views.end(), v));
    }
    EXPECT_EQ(nested_angular_levels(sampling, 2).size(), 2u);
    EXPECT_TRUE(nested_angular_levels(sampling, 0).empty());
}

// A smooth function of a (view, light) pair and a channel.
double smooth(const Vec3& v, const Vec3& l, int c) {
    return 1 + 0.5 * v.z + 0.3 * l.z * l.z + 0.2 * v.x * l.x + 0.1 * c * l.y;
}

TEST(AngularLevels, UpsamplingInterpolatesAndDownsamplingIsItsLeastSquaresInverse) {
    const Sampling sampling{DirectionSet::ubo81(), DirectionSet::ubo81()};
    const std::vector<AngularLevel> levels = nested_angular_levels(sampling, 2);
    const int channels = 3;
    for (const AngularLevel& level : levels) {
        const AngularResampler r(sampling, level, channels);
        const int cv = int(level.views.size()), cl = int(level.lights.size());
        ASSERT_EQ(r.full_rows(), 81 * 81 * channels);
        ASSERT_EQ(r.coarse_rows(), int64_t(cv) * cl * channels);
        std::mt19937 rng(3);
        std::normal_distribution<double> normal;
        Eigen::MatrixXd coarse(r.coarse_rows(), 2);
        for (Eigen::Index i = 0; i < coarse.size(); ++i) coarse.data()[i] = normal(rng);
        const Eigen::MatrixXd full = r.upsample(coarse);
        // Up-sampling is barycentric interpolation through the subsets' own triangulations.
        const AngularInterpolator views(sampling.views.subset(level.views, "v"));
        const AngularInterpolator lights(sampling.lights.subset(level.lights, "l"));
        for (int v = 0; v < 81; v += 7)
            for (int l = 0; l < 81; l += 5) {
                const AngularWeights wv = views.weights(sampling.views.vector(v));
                const AngularWeights wl = lights.weights(sampling.lights.vector(l));
                for (int c = 0; c < channels; ++c) {
                    double want = 0;
                    for (int i = 0; i < wv.count; ++i)
                        for (int j = 0; j < wl.count; ++j)
                            want +=
                                double(wv.weight[i]) * wl.weight[j] *
                                coarse((int64_t(wv.index[i]) * cl + wl.index[j]) * channels + c, 1);
                    ASSERT_NEAR(full((int64_t(v) * 81 + l) * channels + c, 1), want, 1e-6);
                }
            }
        // A full direction in the subset reads itself.
        for (int i = 0; i < cv; ++i)
            ASSERT_NEAR(full((int64_t(level.views[i]) * 81 + level.lights[0]) * channels, 0),
                        coarse(int64_t(i) * cl * channels, 0), 1e-6);
        // D U = I: down-sampling recovers what was up-sampled.
        EXPECT_LT((r.downsample(full) - coarse).cwiseAbs().maxCoeff(), 1e-9);
        // D is the least-squares fit: the residual of a smooth function is orthogonal to the
        // up-sampled columns, and a smooth function is fitted closely.
        Eigen::MatrixXd f(r.full_rows(), 1);
        for (int v = 0; v < 81; ++v)
            for (int l = 0; l < 81; ++l)
                for (int c = 0; c < channels; ++c)
                    f((int64_t(v) * 81 + l) * channels + c, 0) =
                        smooth(sampling.views.vector(v), sampling.lights.vector(l), c);
        const Eigen::MatrixXd fit = r.upsample(r.downsample(f));
        const Eigen::MatrixXd residual = f - fit;
        EXPECT_LT(residual.norm() / f.norm(), 0.02);
        Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(r.coarse_rows(), 1);
        unit(5, 0) = 1;
        EXPECT_NEAR((r.upsample(unit).transpose() * residual)(0, 0), 0, 1e-9);
        // Constants survive exactly (the weights of every direction sum to 1).
        const Eigen::MatrixXd one = Eigen::MatrixXd::Ones(r.full_rows(), 1);
        EXPECT_LT((r.upsample(r.downsample(one)) - one).cwiseAbs().maxCoeff(), 1e-6);
    }
}

TEST(AngularLevels, RejectsBadLevels) {
    const Sampling sampling{DirectionSet::ubo81(), DirectionSet::ubo81()};
    AngularLevel level{{0, 1, 2}, {0, 1, 2}};
    EXPECT_NO_THROW(AngularResampler(sampling, level, 1));
    level.views = {0, 1};
    EXPECT_EQ(test::error_of([&] { AngularResampler(sampling, level, 1); }),
              "angular level: 2 views (at least 3 needed)");
    level.views = {0, 1, 81};
    EXPECT_EQ(test::error_of([&] { AngularResampler(sampling, level, 1); }),
              "angular level: views index 81 outside 0..80");
    level.views = {0, 1, 1};
    EXPECT_EQ(test::error_of([&] { AngularResampler(sampling, level, 1); }),
              "angular level: views index 1 repeated");
    const AngularResampler r(sampling, {{0, 1, 2}, {0, 1, 2}}, 1);
    EXPECT_EQ(test::error_of([&] { r.upsample(Eigen::MatrixXd::Zero(8, 1)); }),
              "angular level: a column of 8 rows, expected 9");
}

}  // namespace
}  // namespace btf::factor
