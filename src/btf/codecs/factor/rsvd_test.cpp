// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/rsvd.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <Eigen/QR>
#include <cmath>
#include <random>

#include "btf/util/error.h"
#include "btf/util/parallel.h"
#include "btf/util/thin_products.h"

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

// A Gaussian rows × rank times rank × cols product: a matrix of exactly that rank.
Matrix low_rank(int rows, int cols, int rank, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<float> normal;
    Matrix a(rows, rank), b(rank, cols);
    for (int64_t i = 0; i < a.size(); ++i) a.data()[i] = normal(rng);
    for (int64_t i = 0; i < b.size(); ++i) b.data()[i] = normal(rng);
    return a * b;
}

// Every test of this suite runs for both methods.
class RandomizedSvd : public ::testing::TestWithParam<SvdMethod> {
  protected:
    SvdOptions with_method() const {
        SvdOptions options;
        options.method = GetParam();
        return options;
    }
};

INSTANTIATE_TEST_SUITE_P(Methods, RandomizedSvd,
                         ::testing::Values(SvdMethod::kSubspace, SvdMethod::kBlockKrylov),
                         [](const auto& info) {
                             return info.param == SvdMethod::kSubspace ? "Subspace" : "Krylov";
                         });

double truncation_error(const Matrix& m, const Svd& svd) {
    Eigen::MatrixXd r = m.cast<double>();
    if (!svd.mean.empty())
        for (int64_t i = 0; i < r.rows(); ++i) r.row(i).array() -= svd.mean[i];
    r -= (svd.u.cast<double>() * svd.sigma.cast<double>().asDiagonal() *
          svd.v.cast<double>().transpose());
    return r.norm();
}

TEST_P(RandomizedSvd, MatchesTheExactTruncatedSvd) {
    // Eckart–Young: the exact truncated SVD is optimal; the randomized one must come within 1 %.
    const Matrix m = decaying(120, 300, 3);
    for (int rank : {4, 16, 40}) {
        const Svd exact = exact_svd(m, rank, false);
        MemoryRows rows({&m}, 7);
        SvdOptions options = with_method();
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

TEST_P(RandomizedSvd, RecoversALowRankMatrixExactly) {
    const Matrix m = low_rank(90, 70, 6, 5);
    MemoryRows rows({&m}, 16);
    SvdOptions options = with_method();
    options.rank = 6;
    options.power_iterations = 0;
    const Svd svd = randomized_svd(rows, options)[0];
    EXPECT_LT(truncation_error(m, svd), 1e-4 * m.norm());
}

TEST_P(RandomizedSvd, MeanCentringMatchesTheExactCentredSvd) {
    Matrix m = decaying(60, 150, 9);
    for (int64_t r = 0; r < m.rows(); ++r) m.row(r).array() += 0.5f + 0.01f * r;
    MemoryRows rows({&m}, 10);
    SvdOptions options = with_method();
    options.rank = 8;
    options.subtract_mean = true;
    const Svd fast = randomized_svd(rows, options)[0];
    const Svd exact = exact_svd(m, 8, true);
    ASSERT_EQ(fast.mean.size(), 60u);
    for (int r = 0; r < 60; ++r) EXPECT_NEAR(fast.mean[r], exact.mean[r], 1e-5);
    EXPECT_LE(truncation_error(m, fast), 1.01 * truncation_error(m, exact));
}

TEST_P(RandomizedSvd, FactorizesSeveralMatricesInTheSamePasses) {
    const Matrix a = decaying(50, 80, 1), b = decaying(30, 80, 2);
    MemoryRows rows({&a, &b}, 9);
    SvdOptions options = with_method();
    options.rank = 5;
    const auto both = randomized_svd(rows, options);
    ASSERT_EQ(both.size(), 2u);
    EXPECT_LE(truncation_error(a, both[0]), 1.01 * truncation_error(a, exact_svd(a, 5, false)));
    EXPECT_LE(truncation_error(b, both[1]), 1.01 * truncation_error(b, exact_svd(b, 5, false)));
}

TEST_P(RandomizedSvd, IsDeterministicForAnyThreadCount) {
    const Matrix m = decaying(80, 5000, 4);
    MemoryRows rows({&m}, 13);
    SvdOptions options = with_method();
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

// The passes' products by btfkit's kernels and by OpenBLAS (util/thin_products.h) differ only in
// rounding: the same factorization within float precision, each deterministic.
TEST_P(RandomizedSvd, GivesTheSameFactorizationWithEitherProductKernel) {
    if (!thin::own_kernel_supported()) GTEST_SKIP() << "no AVX-512F on this CPU";
    const Matrix m = decaying(300, 3000, 5);
    MemoryRows rows({&m}, 37);
    SvdOptions options = with_method();
    options.rank = 12;
    const thin::Kernel saved = thin::kernel();
    Svd by[2];
    for (const thin::Kernel k : {thin::Kernel::kOwn, thin::Kernel::kBlas}) {
        thin::set_kernel(k);
        by[int(k)] = randomized_svd(rows, options)[0];
        EXPECT_EQ(randomized_svd(rows, options)[0].u, by[int(k)].u);
    }
    thin::set_kernel(saved);
    EXPECT_LT((by[0].sigma - by[1].sigma).cwiseAbs().maxCoeff(), 1e-4 * by[0].sigma[0]);
    EXPECT_NEAR(truncation_error(m, by[0]), truncation_error(m, by[1]),
                1e-4 * truncation_error(m, by[1]));
    // Singular vectors up to sign.
    for (int j = 0; j < 12; ++j)
        EXPECT_GT(std::abs(by[0].v.col(j).dot(by[1].v.col(j))), 0.999f) << j;
}

TEST_P(RandomizedSvd, ClampsTheRankToTheMatrix) {
    const Matrix m = decaying(5, 40, 8);
    MemoryRows rows({&m}, 2);
    SvdOptions options = with_method();
    options.rank = 12;
    const Svd svd = randomized_svd(rows, options)[0];
    EXPECT_EQ(svd.sigma.size(), 5);
    EXPECT_LT(truncation_error(m, svd), 1e-4 * m.norm());
}

// The rows of a MemoryRows, handed out only as copies (as a file-backed source does), counting
// the batches read.
class CopiedRows final : public RowBatches {
  public:
    explicit CopiedRows(const MemoryRows& rows) : m_rows(rows) {}
    int matrices() const override { return m_rows.matrices(); }
    int64_t rows(int m) const override { return m_rows.rows(m); }
    int64_t cols(int m) const override { return m_rows.cols(m); }
    int batches() const override { return m_rows.batches(); }
    void read(int batch, std::vector<int64_t>& first, std::vector<Matrix>& out) const override {
        ++reads;
        m_rows.read(batch, first, out);
    }
    int64_t batch_rows(int batch, int m) const override { return m_rows.batch_rows(batch, m); }
    mutable int reads = 0;

  private:
    const MemoryRows& m_rows;
};

TEST_P(RandomizedSvd, RowsInMemoryGiveTheSameBitsAsRowsRead) {
    // MemoryRows multiplies its rows where they are; a source's rows are read into a batch.
    const Matrix a = decaying(70, 3000, 11), b = decaying(40, 3000, 12);
    const MemoryRows viewed({&a, &b}, 9);
    const CopiedRows copied(viewed);
    SvdOptions options = with_method();
    options.rank = 7;
    const auto x = randomized_svd(viewed, options), y = randomized_svd(copied, options);
    // Block Krylov reads up to 16 batches once more for its start.
    const int start = GetParam() == SvdMethod::kBlockKrylov ? std::min(16, viewed.batches()) : 0;
    EXPECT_EQ(copied.reads, svd_passes(options) * viewed.batches() + start);
    for (int m = 0; m < 2; ++m) {
        EXPECT_EQ(x[m].u, y[m].u);
        EXPECT_EQ(x[m].v, y[m].v);
        EXPECT_EQ(x[m].sigma, y[m].sigma);
        EXPECT_EQ(x[m].total_energy, y[m].total_energy);
    }
}

TEST(BlockKrylov, ReadsTheSourceQPlusTwoTimes) {
    const Matrix m = decaying(60, 400, 13);
    const MemoryRows memory({&m}, 8);
    for (int q : {0, 1, 4}) {
        const CopiedRows rows(memory);
        SvdOptions options;
        options.method = SvdMethod::kBlockKrylov;
        options.rank = 6;
        options.power_iterations = q;
        randomized_svd(rows, options);
        EXPECT_EQ(svd_passes(options), q + 2);
        // And the 8 batches once more for the start: rows sampled from them.
        EXPECT_EQ(rows.reads, (q + 2) * memory.batches() + 8) << "q = " << q;
    }
    SvdOptions subspace;
    subspace.power_iterations = 3;
    EXPECT_EQ(svd_passes(subspace), 8);
}

TEST(BlockKrylov, MatchesSubspaceIterationWithFewerPassesAndProducts) {
    // A slowly decaying spectrum: block Krylov with q = 3 (5 passes, 9 products of 12 columns)
    // against subspace iteration with q = 3 (8 passes of 30 columns).
    const Matrix m = decaying(200, 600, 14);
    const MemoryRows rows({&m}, 16);
    SvdOptions krylov, subspace;
    krylov.method = SvdMethod::kBlockKrylov;
    krylov.rank = subspace.rank = 20;
    krylov.power_iterations = subspace.power_iterations = 3;
    const double exact = truncation_error(m, exact_svd(m, 20, false));
    const double k = truncation_error(m, randomized_svd(rows, krylov)[0]);
    const double s = truncation_error(m, randomized_svd(rows, subspace)[0]);
    EXPECT_LE(k, 1.001 * s);
    EXPECT_LE(k, 1.01 * exact);
    EXPECT_GE(k, exact * (1 - 1e-4));
}

TEST(BlockKrylov, KeepsItsBlocksOrthonormalForALowRankMatrix) {
    // Rank 3, but 5 blocks of 8: the blocks after the second find nothing new and must still be
    // orthonormal, or the Rayleigh–Ritz step would invent energy.
    const Matrix m = low_rank(50, 120, 3, 15);
    const MemoryRows rows({&m}, 7);
    SvdOptions options;
    options.method = SvdMethod::kBlockKrylov;
    options.rank = 5;
    options.block = 8;
    options.power_iterations = 3;
    const Svd svd = randomized_svd(rows, options)[0];
    EXPECT_LT(truncation_error(m, svd), 1e-4 * m.norm());
    EXPECT_LE(svd.sketch_energy, svd.total_energy * (1 + 1e-5));
    EXPECT_LT((svd.u.transpose() * svd.u - Matrix::Identity(5, 5)).norm(), 1e-4);
    EXPECT_LT((svd.v.transpose() * svd.v - Matrix::Identity(5, 5)).norm(), 1e-4);
    EXPECT_LT(svd.sigma[3], 1e-4 * svd.sigma[0]);
}

// Explicit linear maps around a matrix: L (rows × rows) and R (cols × cols), neither symmetric.
class DenseTransforms final : public Transforms {
  public:
    DenseTransforms(Eigen::MatrixXd l, Eigen::MatrixXd r) : m_l(std::move(l)), m_r(std::move(r)) {}
    void left(int, Matrix& y, bool transpose) const override {
        const Eigen::MatrixXd x = y.cast<double>();
        y = (transpose ? Eigen::MatrixXd(m_l.transpose() * x) : Eigen::MatrixXd(m_l * x))
                .cast<float>();
    }
    void right(int, Matrix& z, bool transpose) const override {
        const Eigen::MatrixXd x = z.cast<double>();
        z = (transpose ? Eigen::MatrixXd(m_r.transpose() * x) : Eigen::MatrixXd(m_r * x))
                .cast<float>();
    }
    const Eigen::MatrixXd& l() const { return m_l; }
    const Eigen::MatrixXd& r() const { return m_r; }

  private:
    Eigen::MatrixXd m_l, m_r;
};

// A well-conditioned, non-symmetric n × n matrix: I + a random perturbation.
Eigen::MatrixXd invertible(int n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    Eigen::MatrixXd m = Eigen::MatrixXd::Identity(n, n);
    for (int64_t i = 0; i < m.size(); ++i) m.data()[i] += 0.4 * normal(rng) / std::sqrt(n);
    return m;
}

// P Σ Qᵀ of the first k triplets.
Eigen::MatrixXd product(const Svd& svd, int k) {
    return svd.u.leftCols(k).cast<double>() * svd.sigma.head(k).cast<double>().asDiagonal() *
           svd.v.leftCols(k).cast<double>().transpose();
}

TEST_P(RandomizedSvd, TransformedFactorizesTheTransformedMatrixWithoutFormingIt) {
    const Matrix m = decaying(40, 90, 21);
    const DenseTransforms maps(invertible(40, 1), invertible(90, 2));
    const Matrix transformed = (maps.l() * m.cast<double>() * maps.r().transpose()).cast<float>();
    MemoryRows rows({&m}, 7);
    SvdOptions options = with_method();
    options.rank = 6;
    options.transforms = &maps;
    const Svd fast = randomized_svd(rows, options)[0];
    const Svd exact = exact_svd(transformed, 6, false);
    EXPECT_LE(truncation_error(transformed, fast), 1.01 * truncation_error(transformed, exact));
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(fast.sigma[k], exact.sigma[k], 1e-3 * exact.sigma[0]);
    // The sketch's energy: the transformed matrix's within the sketched subspace.
    EXPECT_LE(fast.sketch_energy, transformed.cast<double>().squaredNorm() * (1 + 1e-5));
    EXPECT_GE(fast.sketch_energy, exact.sigma.cast<double>().squaredNorm() * (1 - 1e-5));
    EXPECT_NEAR(fast.total_energy, m.cast<double>().squaredNorm(), 1e-5 * fast.total_energy);
}

// §5.4 of Guthe et al.: the untransformed factors a = M Rᵀ Q Σ⁻¹, b = Mᵀ Lᵀ P reproduce
// L⁻¹ P Σ Qᵀ R⁻ᵀ exactly for an exact SVD of L M Rᵀ, without inverting L or R.
TEST(TransformedSvd, UntransformedFactorsEqualTheInverseTransformOfTheApproximation) {
    const Matrix m = decaying(24, 36, 5);
    const DenseTransforms maps(invertible(24, 3), invertible(36, 4));
    const Matrix transformed = (maps.l() * m.cast<double>() * maps.r().transpose()).cast<float>();
    MemoryRows rows({&m}, 5);
    for (int k : {1, 8, 24}) {
        const Svd exact = exact_svd(transformed, k, false);
        const Factors f = untransformed_factors(rows, maps, {exact}, {k})[0];
        ASSERT_EQ(f.a.rows(), 24);
        ASSERT_EQ(f.b.rows(), 36);
        ASSERT_EQ(f.a.cols(), k);
        const Eigen::MatrixXd expected =
            maps.l().inverse() * product(exact, k) * maps.r().inverse().transpose();
        const Eigen::MatrixXd got = f.a.cast<double>() * f.b.cast<double>().transpose();
        EXPECT_LT((got - expected).norm(), 1e-4 * expected.norm()) << "rank " << k;
        // Their transforms are the transformed factors: L a = P, R b = Q Σ.
        EXPECT_LT((maps.l() * f.a.cast<double>() - exact.u.cast<double>()).norm(), 1e-4 * k);
        // At full rank the approximation is the matrix itself.
        if (k == 24) EXPECT_LT((got - m.cast<double>()).norm(), 1e-4 * m.norm());
    }
}

TEST_P(RandomizedSvd, TransformedUntransformedFactorsOfACentredRandomizedSvd) {
    Matrix m = decaying(30, 50, 6);
    for (int64_t r = 0; r < m.rows(); ++r) m.row(r).array() += 1.0f + 0.05f * r;
    const DenseTransforms maps(invertible(30, 7), invertible(50, 8));
    MemoryRows rows({&m}, 4);
    SvdOptions options = with_method();
    options.rank = 30;  // full rank: the sketch is exact
    options.subtract_mean = true;
    options.transforms = &maps;
    const Svd svd = randomized_svd(rows, options)[0];
    ASSERT_EQ(svd.mean.size(), 30u);
    for (int k : {5, 29}) {
        const Factors f = untransformed_factors(rows, maps, {svd}, {k})[0];
        const Eigen::MatrixXd expected =
            maps.l().inverse() * product(svd, k) * maps.r().inverse().transpose();
        const Eigen::MatrixXd got = f.a.cast<double>() * f.b.cast<double>().transpose();
        EXPECT_LT((got - expected).norm(), 1e-3 * expected.norm()) << "rank " << k;
    }
    // All 30 components give the centred matrix back.
    const Factors all = untransformed_factors(rows, maps, {svd}, {30})[0];
    Eigen::MatrixXd centred = m.cast<double>();
    for (int r = 0; r < 30; ++r) centred.row(r).array() -= svd.mean[r];
    EXPECT_LT((all.a.cast<double>() * all.b.cast<double>().transpose() - centred).norm(),
              1e-3 * centred.norm());
}

TEST(TransformedSvd, RejectsAZeroSingularValue) {
    const Matrix m = Matrix::Zero(6, 8);
    const DenseTransforms maps(invertible(6, 1), invertible(8, 2));
    MemoryRows rows({&m}, 3);
    const Svd svd = exact_svd(m, 2, false);
    try {
        untransformed_factors(rows, maps, {svd}, {2});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(), "untransformed factors: SVD 0 keeps a zero singular value");
    }
}

}  // namespace
}  // namespace btf::factor
