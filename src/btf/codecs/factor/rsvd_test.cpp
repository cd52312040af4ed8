#include "btf/codecs/factor/rsvd.h"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <random>

#include "btf/util/parallel.h"

namespace btf::factor {
namespace {

// A matrix with a slowly decaying spectrum (σ_i = 1 / (1 + i)^0.7), like BTF matrices.
Matrix decaying(int rows, int cols, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    Eigen::MatrixXd a(rows, rows), b(cols, rows);
    for (int64_t i = 0; i < a.size(); ++i) a.data()[i] = normal(rng);
    for (int64_t i = 0; i < b.size(); ++i) b.data()[i] = normal(rng);
    const Eigen::MatrixXd qa = Eigen::HouseholderQR<Eigen::MatrixXd>(a).householderQ();
    const Eigen::MatrixXd qb = Eigen::HouseholderQR<Eigen::MatrixXd>(b).householderQ() *
                               Eigen::MatrixXd::Identity(cols, rows);
    Eigen::VectorXd s(rows);
    for (int i = 0; i < rows; ++i) s[i] = 1.0 / std::pow(1.0 + i, 0.7);
    return (qa * s.asDiagonal() * qb.transpose()).cast<float>();
}

double truncation_error(const Matrix& m, const Svd& svd) {
    Eigen::MatrixXd r = m.cast<double>();
    if (!svd.mean.empty())
        for (int64_t i = 0; i < r.rows(); ++i) r.row(i).array() -= svd.mean[i];
    r -= (svd.u.cast<double>() * svd.sigma.cast<double>().asDiagonal() *
          svd.v.cast<double>().transpose());
    return r.norm();
}

TEST(RandomizedSvd, MatchesTheExactTruncatedSvd) {
    // Eckart–Young: the exact truncated SVD is optimal; the randomized one must come within 1 %.
    const Matrix m = decaying(120, 300, 3);
    for (int rank : {4, 16, 40}) {
        const Svd exact = exact_svd(m, rank, false);
        MemoryRows rows({&m}, 7);
        SvdOptions options;
        options.rank = rank;
        const Svd fast = randomized_svd(rows, options)[0];
        const double e_exact = truncation_error(m, exact), e_fast = truncation_error(m, fast);
        EXPECT_LE(e_fast, 1.01 * e_exact) << "rank " << rank;
        EXPECT_GE(e_fast, e_exact * (1 - 1e-4)) << "rank " << rank;  // nothing beats the optimum
        // The energy identity: ‖M − M_k‖² = ‖M‖² − Σσ².
        EXPECT_NEAR(e_fast * e_fast, fast.total_energy - fast.sigma.cast<double>().squaredNorm(),
                    1e-3 * fast.total_energy);
        // Orthonormal factors.
        EXPECT_LT((fast.u.transpose() * fast.u - Matrix::Identity(rank, rank)).norm(), 1e-4);
        EXPECT_LT((fast.v.transpose() * fast.v - Matrix::Identity(rank, rank)).norm(), 1e-4);
    }
}

TEST(RandomizedSvd, RecoversALowRankMatrixExactly) {
    std::mt19937_64 rng(5);
    std::normal_distribution<float> normal;
    Matrix a(90, 6), b(6, 70);
    for (int64_t i = 0; i < a.size(); ++i) a.data()[i] = normal(rng);
    for (int64_t i = 0; i < b.size(); ++i) b.data()[i] = normal(rng);
    const Matrix m = a * b;
    MemoryRows rows({&m}, 16);
    SvdOptions options;
    options.rank = 6;
    options.power_iterations = 0;
    const Svd svd = randomized_svd(rows, options)[0];
    EXPECT_LT(truncation_error(m, svd), 1e-4 * m.norm());
}

TEST(RandomizedSvd, MeanCentringMatchesTheExactCentredSvd) {
    Matrix m = decaying(60, 150, 9);
    for (int64_t r = 0; r < m.rows(); ++r) m.row(r).array() += 0.5f + 0.01f * r;
    MemoryRows rows({&m}, 10);
    SvdOptions options;
    options.rank = 8;
    options.subtract_mean = true;
    const Svd fast = randomized_svd(rows, options)[0];
    const Svd exact = exact_svd(m, 8, true);
    ASSERT_EQ(fast.mean.size(), 60u);
    for (int r = 0; r < 60; ++r) EXPECT_NEAR(fast.mean[r], exact.mean[r], 1e-5);
    EXPECT_LE(truncation_error(m, fast), 1.01 * truncation_error(m, exact));
}

TEST(RandomizedSvd, FactorizesSeveralMatricesInTheSamePasses) {
    const Matrix a = decaying(50, 80, 1), b = decaying(30, 80, 2);
    MemoryRows rows({&a, &b}, 9);
    SvdOptions options;
    options.rank = 5;
    const auto both = randomized_svd(rows, options);
    ASSERT_EQ(both.size(), 2u);
    EXPECT_LE(truncation_error(a, both[0]), 1.01 * truncation_error(a, exact_svd(a, 5, false)));
    EXPECT_LE(truncation_error(b, both[1]), 1.01 * truncation_error(b, exact_svd(b, 5, false)));
}

TEST(RandomizedSvd, IsDeterministicForAnyThreadCount) {
    const Matrix m = decaying(80, 5000, 4);
    MemoryRows rows({&m}, 13);
    SvdOptions options;
    options.rank = 10;
    Svd one, two;
    {
        ThreadLimit limit(1);
        one = randomized_svd(rows, options)[0];
    }
    {
        ThreadLimit limit(2);
        two = randomized_svd(rows, options)[0];
    }
    EXPECT_EQ(one.u, two.u);
    EXPECT_EQ(one.v, two.v);
    EXPECT_EQ(one.sigma, two.sigma);
}

TEST(RandomizedSvd, ClampsTheRankToTheMatrix) {
    const Matrix m = decaying(5, 40, 8);
    MemoryRows rows({&m}, 2);
    SvdOptions options;
    options.rank = 12;
    const Svd svd = randomized_svd(rows, options)[0];
    EXPECT_EQ(svd.sigma.size(), 5);
    EXPECT_LT(truncation_error(m, svd), 1e-4 * m.norm());
}

}  // namespace
}  // namespace btf::factor
