// SPDX-License-Identifier: MIT
#include "btf/quality/lowrank.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cstdio>
#include <filesystem>
#include <map>
#include <random>

#include "btf/io/function_source.h"
#include "btf/util/error.h"

namespace btf {
namespace {

using ::testing::HasSubstr;

// A BtfSource over an explicit matrix: one view, rows = texels, column 3·light + channel.
FunctionSource matrix_source(int width, int height, Eigen::MatrixXd matrix) {
    std::vector<Direction> lights;
    for (int l = 0; l < matrix.cols() / 3; ++l)
        lights.push_back(Direction::from_degrees(10.0 * l / 3, 7.0 * l));
    Sampling sampling{DirectionSet("one", {Direction{}}), DirectionSet("lights", lights)};
    return FunctionSource(
        std::move(sampling), width, height,
        [width, m = std::move(matrix)](int, int light, int x, int y) {
            const int64_t p = int64_t(y) * width + x;
            return Rgb{float(m(p, 3 * light)), float(m(p, 3 * light + 1)),
                       float(m(p, 3 * light + 2))};
        },
        "test matrix");
}

// Float-exact random matrix (the source hands out floats).
Eigen::MatrixXd random_matrix(int rows, int cols, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
    Eigen::MatrixXd m(rows, cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) m(i, j) = double(uniform(rng));
    return m;
}

TEST(LowRank, MatchesExplicitSvd) {
    const int width = 7, height = 5, lights = 6;
    const Eigen::MatrixXd a = random_matrix(width * height, 3 * lights, 42);
    const FunctionSource source = matrix_source(width, height, a);
    const std::vector<int> ranks = {0, 1, 2, 4, 8, 17, 18, 40};
    const LowRankError e = light_matrix_low_rank(source, 0, ranks);

    const Eigen::BDCSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const Eigen::VectorXd s = svd.singularValues();
    const double total = s.squaredNorm();
    ASSERT_EQ(e.relative_rmse.size(), ranks.size());
    EXPECT_EQ(e.rows, width * height);
    EXPECT_EQ(e.cols, 3 * lights);
    EXPECT_NEAR(e.rms, std::sqrt(a.squaredNorm() / a.size()), 1e-12);
    for (size_t i = 0; i < ranks.size(); ++i) {
        double tail = 0;
        for (int k = ranks[i]; k < s.size(); ++k) tail += s[k] * s[k];
        EXPECT_NEAR(e.relative_rmse[i], std::sqrt(tail / total), 1e-9) << "rank " << ranks[i];
        EXPECT_NEAR(e.energy[i], 1 - tail / total, 1e-9) << "rank " << ranks[i];
        // The same number from an explicit truncated reconstruction (Eckart–Young).
        const int k = std::min<int>(ranks[i], int(s.size()));
        const Eigen::MatrixXd ak = svd.matrixU().leftCols(k) * s.head(k).asDiagonal() *
                                   svd.matrixV().leftCols(k).transpose();
        const double rmse = std::sqrt((a - ak).squaredNorm() / a.size());
        EXPECT_NEAR(e.relative_rmse[i], rmse / e.rms, 1e-9) << "rank " << ranks[i];
    }
    ASSERT_EQ(e.eigenvalues.size(), size_t(3 * lights));
    for (int i = 0; i < s.size(); ++i) EXPECT_NEAR(e.eigenvalues[i], s[i] * s[i], 1e-9 * total);
}

TEST(LowRank, ZeroForExactRankK) {
    const int width = 9, height = 8, lights = 10, k = 4;
    const Eigen::MatrixXd u = random_matrix(width * height, k, 1);
    const Eigen::MatrixXd v = random_matrix(3 * lights, k, 2);
    const FunctionSource source = matrix_source(width, height, u * v.transpose());
    const LowRankError e = light_matrix_low_rank(source, 0, {k - 1, k, k + 3});
    EXPECT_GT(e.relative_rmse[0], 1e-3);
    // Floats in the images limit the exactness to about their precision.
    EXPECT_LT(e.relative_rmse[1], 1e-6);
    EXPECT_LT(e.relative_rmse[2], 1e-6);
}

TEST(LowRank, BandsGiveTheSameResult) {
    const int width = 6, height = 11, lights = 5;
    const FunctionSource source =
        matrix_source(width, height, random_matrix(width * height, 3 * lights, 7));
    const LowRankError whole = light_matrix_low_rank(source, 0, {1, 2, 3, 6});
    LowRankOptions options;
    options.band_bytes = 1;  // one texel row per band
    const LowRankError banded = light_matrix_low_rank(source, 0, {1, 2, 3, 6}, options);
    for (size_t i = 0; i < whole.relative_rmse.size(); ++i)
        EXPECT_NEAR(whole.relative_rmse[i], banded.relative_rmse[i], 1e-12);
}

TEST(LowRank, ErrorsNameTheProblem) {
    const FunctionSource source = matrix_source(4, 4, random_matrix(16, 6, 3));
    try {
        light_matrix_low_rank(source, 1, {1});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(e.what(), HasSubstr("view 1 is outside [0, 1)"));
    }
    try {
        light_matrix_low_rank(source, 0, {-2});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(e.what(), HasSubstr("rank -2 is negative"));
    }
    try {
        light_matrix_low_rank(5, 4, 2, [](int, Image& out) { out = Image(4, 4, 3); }, {1});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(e.what(), HasSubstr("is 4x4x3, expected 5x4x3"));
    }
}

// The reference numbers of ../shared/data/README.md, from the real JPEGs decoded to linear.
TEST(LowRank, RealUbo2003ViewMatchesReference) {
    namespace fs = std::filesystem;
    const fs::path folder =
        fs::path(BTF_SHARED_DIR) / "data" / "ubo2003-proposte-view000" / "tv000_pv000";
    if (!fs::is_directory(folder)) GTEST_SKIP() << folder << " is absent";
    std::map<int, fs::path> files;
    for (const auto& entry : fs::directory_iterator(folder)) {
        int number, tl, pl, tv, pv;
        if (std::sscanf(entry.path().filename().string().c_str(), "%d tl%d pl%d tv%d pv%d", &number,
                        &tl, &pl, &tv, &pv) == 5)
            files[DirectionSet::ubo81().find(Direction::from_degrees(tl, pl))] = entry.path();
    }
    ASSERT_EQ(files.size(), 81u);
    ASSERT_EQ(files.begin()->first, 0);
    const LowRankError e = light_matrix_low_rank(
        256, 256, 81, [&](int light, Image& out) { out = read_image(files.at(light)); },
        {1, 4, 8, 16, 32});
    const double expected[] = {0.219, 0.157, 0.111, 0.082, 0.055};
    for (int i = 0; i < 5; ++i) EXPECT_NEAR(e.relative_rmse[i], expected[i], 0.0015) << i;
    EXPECT_NEAR(e.energy[0], 0.952, 0.001);
}

}  // namespace
}  // namespace btf
