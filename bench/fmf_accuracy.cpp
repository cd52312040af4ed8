// SPDX-License-Identifier: MIT
// Accuracy of the fmf codec's streaming randomized SVD against the exact truncated SVD of the same
// matrix (Eckart–Young: no rank-C approximation has a smaller Frobenius error).
//
// The matrix is the fmf rgb-mode matrix of a synthetic material (rows: view · light · 3 colour
// channels, columns: texels; 19683 × 4096 at the default 64² × 81 × 81). The exact rank-C error
// is the tail of the spectrum: the eigenvalues of the Gram matrix MᵀM (texels × texels), computed
// in double by Eigen's SelfAdjointEigenSolver. fmf's error is measured explicitly, ‖M − A Bᵀ‖_F,
// for the factors fmf::factorize returns (float) and after the package's default f16 storage.
// Prints a Markdown table for docs/benchmarks.md.
//
//   build/<dir>/fmf_accuracy [--size 64] [--preset woven_fabric] [--seed 1] [--components 8,32,64]

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/factor/params.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/synth/synth.h"
#include "btf/util/blas.h"
#include "btf/util/thin_products.h"

namespace {

using namespace btf;

// ‖M − A Bᵀ‖²_F in double, over fixed row chunks (deterministic for any thread count).
double residual_energy(const factor::Matrix& m, const factor::Matrix& a, const factor::Matrix& b) {
    constexpr int64_t kChunk = 243;
    const int64_t chunks = (m.rows() + kChunk - 1) / kChunk;
    std::vector<double> sums(chunks, 0.0);
    parallel_for(0, chunks, [&](int64_t c) {
        const int64_t r0 = c * kChunk, n = std::min(kChunk, m.rows() - r0);
        const factor::Matrix d = m.middleRows(r0, n) - a.middleRows(r0, n) * b.transpose();
        sums[c] = d.cast<double>().squaredNorm();
    });
    double total = 0;
    for (double s : sums) total += s;
    return total;
}

}  // namespace

int main(int argc, char** argv) {
    int size = 64;
    uint64_t seed = 1;
    std::string preset = "woven_fabric";
    std::vector<int> ranks = {8, 32, 64};
    CLI::App app{"fmf's error against the exact truncated SVD (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--seed", seed, "synthesis seed")->capture_default_str();
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--components", ranks, "ranks to compare")->delimiter(',');
    std::vector<std::string> configs = {"default"};
    app.add_option("--configs", configs,
                   "randomized SVD configurations: default, or method:q[:block] "
                   "(subspace:3, krylov:2:40)")
        ->delimiter(',');
    CLI11_PARSE(app, argc, argv);
    try {
        const DirectionSet& ubo = DirectionSet::ubo81();
        bench::Stopwatch clock;
        const bench::MemorySource source(*synth::make(preset, size, {ubo, ubo}, seed));
        std::fprintf(stderr, "synthesized %s %d² × 81 × 81 in %.1f s\n", preset.c_str(), size,
                     clock.seconds());

        // The fmf rgb matrix, read through the same row batches fmf factorizes.
        std::vector<int> all_views(source.num_views());
        for (int v = 0; v < source.num_views(); ++v) all_views[v] = v;
        const factor::SourceRows rows(source, factor::ColourHandling{}, {all_views});
        factor::Matrix m(rows.rows(0), rows.cols(0));
        {
            std::vector<int64_t> first;
            std::vector<factor::Matrix> batch;
            for (int b = 0; b < rows.batches(); ++b) {
                rows.read(b, first, batch);
                m.middleRows(first[0], batch[0].rows()) = batch[0];
            }
        }
        const double total = m.cast<double>().squaredNorm();

        // Gram matrix MᵀM in double: two fixed row halves on two threads, summed in order.
        clock = bench::Stopwatch();
        const int64_t n = m.cols(), half = (m.rows() + 1) / 2;
        std::vector<Eigen::MatrixXd> grams(2, Eigen::MatrixXd::Zero(n, n));
        parallel_for(0, 2, [&](int64_t h) {
            constexpr int64_t kSlice = 1024;
            const int64_t begin = h * half, end = std::min<int64_t>(m.rows(), begin + half);
            for (int64_t r = begin; r < end; r += kSlice) {
                const Eigen::MatrixXd slice =
                    m.middleRows(r, std::min(kSlice, end - r)).cast<double>();
                grams[h].selfadjointView<Eigen::Lower>().rankUpdate(slice.transpose());
            }
        });
        grams[0] += grams[1];
        grams.pop_back();
        const double gram_seconds = clock.seconds();
        clock = bench::Stopwatch();
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(grams[0],
                                                                   Eigen::EigenvaluesOnly);
        if (eigen.info() != Eigen::Success) fail("eigen-decomposition of the Gram matrix failed");
        const double eigen_seconds = clock.seconds();
        std::fprintf(stderr, "matrix %lld × %lld; Gram %.1f s, eigenvalues %.1f s\n",
                     static_cast<long long>(m.rows()), static_cast<long long>(m.cols()),
                     gram_seconds, eigen_seconds);
        const Eigen::VectorXd& lambda = eigen.eigenvalues();  // ascending

        std::printf("products: %s; %s\n\n", std::string(thin::kernel_name()).c_str(),
                    blas::description().c_str());
        std::printf(
            "| C | exact rel. error | randomized SVD | passes | fmf rel. error | ratio fmf / "
            "exact | fmf, f16 package | fmf time |\n|---|---|---|---|---|---|---|---|\n");
        for (int c : ranks)
            for (const std::string& config : configs) {
                double tail = 0;  // the n − C smallest eigenvalues, summed from the smallest
                for (int64_t i = 0; i < n - c; ++i) tail += std::max(0.0, lambda[i]);
                const double exact = std::sqrt(tail / total);

                fmf::Options options;  // the codec's defaults, or the configuration's method and q
                options.components = c;
                if (config != "default") {
                    const bench::SvdConfig parsed = bench::parse_svd_config(config);
                    options.svd = parsed.method;
                    if (parsed.power_iterations >= 0)
                        options.power_iterations = parsed.power_iterations;
                    if (parsed.block >= 0) options.block = parsed.block;
                    if (parsed.oversampling >= 0) options.oversampling = parsed.oversampling;
                }
                factor::SvdOptions svd = factor::svd_options(options, c, false);
                const std::string name = fmt::format(
                    "{}{}, q = {}{}", config == "default" ? "default: " : "",
                    options.svd == factor::SvdMethod::kBlockKrylov ? "krylov" : "subspace",
                    options.power_iterations,
                    options.block > 0 ? fmt::format(", block {}", options.block) : "");
                clock = bench::Stopwatch();
                const factor::Model model = fmf::factorize(source, options);
                const double seconds = clock.seconds();
                const factor::Block& block = model.blocks.at(0);
                const double fmf = std::sqrt(residual_energy(m, block.a, block.b) / total);

                const factor::Model stored = factor::from_package(factor::to_package(
                    model, "fmf", nlohmann::json::object(), options.quantization));
                const factor::Block& sb = stored.blocks.at(0);
                const double packaged = std::sqrt(residual_energy(m, sb.a, sb.b) / total);
                std::printf("| %d | %.5f | %s | %d | %.5f | %.4f | %.5f | %.2f s |\n", c, exact,
                            name.c_str(), factor::svd_passes(svd), fmf, fmf / exact, packaged,
                            seconds);
                std::fflush(stdout);
            }
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "fmf_accuracy: %s\n", e.what());
        return 1;
    }
    return 0;
}
