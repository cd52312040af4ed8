// FactorCodec::encode_to_size: a factorization package of at most a given size at the lowest
// error found (btf compress --target-size).

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "btf/codecs/factor/model.h"
#include "btf/util/error.h"

namespace btf::factor {

namespace {

// The block and k of a component section ("b<block>.k<k>"), or false for another section.
bool component_of(const PackageSection& s, std::pair<int, int>& id) {
    char tail = 0;
    return std::sscanf(s.name.c_str(), "b%d.k%d%c", &id.first, &id.second, &tail) == 2;
}

// Components per block in the first n sections of `order`.
std::vector<int> kept_per_block(const std::vector<std::pair<int, int>>& order, size_t blocks,
                                size_t n) {
    std::vector<int> kept(blocks, 0);
    for (size_t i = 0; i < n; ++i) ++kept[size_t(order[i].first)];
    return kept;
}

Model truncated(const Model& model, const std::vector<int>& kept) {
    Model out = model;
    for (size_t i = 0; i < out.blocks.size(); ++i) {
        Block& b = out.blocks[i];
        const int k = kept[i];
        b.a = model.blocks[i].a.leftCols(k).eval();
        b.b = model.blocks[i].b.leftCols(k).eval();
        b.energy.resize(size_t(k));
    }
    return out;
}

// ‖Σ_k a_k b_kᵀ − Σ_{j<m} â_j b̂_jᵀ‖² of one block for every m, from the Gram matrices of the
// factors (in double): tr(AᵀA BᵀB) − 2 Σ_{j<m} Σ_k (AᵀÂ)_kj (BᵀB̂)_kj
// + Σ_{j,l<m} (ÂᵀÂ)_jl (B̂ᵀB̂)_jl.
std::vector<double> prefix_errors(const Block& exact, const Block& decoded) {
    const Eigen::MatrixXd a = exact.a.cast<double>(), b = exact.b.cast<double>();
    const Eigen::MatrixXd ah = decoded.a.cast<double>(), bh = decoded.b.cast<double>();
    const Eigen::MatrixXd g1 = a.transpose() * ah, h1 = b.transpose() * bh;
    const Eigen::MatrixXd g2 = ah.transpose() * ah, h2 = bh.transpose() * bh;
    const double total = ((a.transpose() * a) * (b.transpose() * b)).trace();
    const int n = int(ah.cols());
    std::vector<double> out(size_t(n) + 1);
    double e = total;
    out[0] = e;
    for (int m = 1; m <= n; ++m) {
        const int j = m - 1;
        e -= 2 * g1.col(j).dot(h1.col(j));
        double cross = g2(j, j) * h2(j, j);
        for (int l = 0; l < j; ++l) cross += 2 * g2(j, l) * h2(j, l);
        e += cross;
        out[size_t(m)] = e;
    }
    return out;
}

struct Candidate {
    double quality;
    size_t sections;  // component sections kept
    uint64_t bytes;   // estimated (from the full package's section sizes)
    double error;     // squared
};

}  // namespace

Package FactorCodec::encode_to_size(const BtfSource& source, const Params& params, uint64_t bytes,
                                    const PackageWriteOptions& write, Progress& progress,
                                    SizeChoice* choice) const {
    const Result result = factorize(source, params, progress);
    const Model& model = result.model;
    const bool coded = result.quantization == Quantization::kCoded;
    auto package_at = [&](const Model& m, double quality) {
        nlohmann::json p = result.params;
        if (coded) p["quality"] = quality;
        Package package = to_package(m, name(), p, result.quantization, quality);
        encode_package(package, write);
        return package;
    };

    // For one quality: every prefix's estimated size and error.
    std::vector<std::pair<int, int>> order;
    auto candidates_at = [&](double quality, std::vector<Candidate>& out) {
        const Package full = package_at(model, quality);
        const bool first = order.empty();
        const Model decoded = from_package(full);
        std::vector<std::vector<double>> errors;
        for (size_t i = 0; i < model.blocks.size(); ++i)
            errors.push_back(prefix_errors(model.blocks[i], decoded.blocks[i]));
        // Bytes without the component sections, with all of them (full) and with none (the
        // header's energies and section entries grow with the components kept: interpolated).
        std::vector<uint64_t> component_bytes;
        uint64_t rest_full = full.file_bytes;
        for (const PackageSection& s : full.sections) {
            std::pair<int, int> id;
            if (!component_of(s, id)) continue;
            if (first) order.push_back(id);  // the package's order, the same at every quality
            component_bytes.push_back(s.stored_size);
            rest_full -= s.stored_size;
        }
        const uint64_t rest_none =
            package_at(truncated(model, std::vector<int>(model.blocks.size(), 0)), quality)
                .file_bytes;
        const size_t total = component_bytes.size();
        uint64_t sections = 0;
        std::vector<int> kept(model.blocks.size(), 0);
        for (size_t n = 0; n <= order.size(); ++n) {
            if (n > 0) {
                sections += component_bytes[n - 1];
                ++kept[size_t(order[n - 1].first)];
            }
            const uint64_t size =
                sections + rest_none +
                uint64_t(std::ceil(double(rest_full - std::min(rest_full, rest_none)) * double(n) /
                                   double(std::max<size_t>(total, 1))));
            double error = 0;
            for (size_t i = 0; i < kept.size(); ++i) error += errors[i][size_t(kept[i])];
            if (n > 0) out.push_back({quality, n, size, error});
        }
    };
    std::vector<Candidate> all;
    auto best_fitting = [&](uint64_t limit) {
        const Candidate* best = nullptr;
        for (const Candidate& c : all)
            if (c.bytes <= limit && (!best || c.error < best->error)) best = &c;
        return best;
    };
    // Qualities: a coarse grid, then finer steps around the best that fits (coded storage);
    // other storages have one "quality".
    const uint64_t limit = bytes;
    if (coded) {
        for (double q = 0; q <= 100; q += 10) candidates_at(q, all);
        for (const double step : {2.0, 0.5}) {
            const Candidate* best = best_fitting(limit);
            if (!best) break;
            const double centre = best->quality;
            for (int i = -4; i <= 4; ++i) {
                const double q = centre + i * step;
                if (i != 0 && q >= 0 && q <= 100) candidates_at(q, all);
            }
        }
    } else {
        candidates_at(kDefaultCodingQuality, all);
    }
    const Candidate* best = best_fitting(limit);
    if (!best)
        fail("--target-size {}: even one component{} takes more", bytes,
             coded ? " at quality 0" : fmt::format(" in {}", to_string(result.quantization)));
    // The chosen prefix for real; should it not fit after all, one component fewer.
    Candidate chosen = *best;
    for (;;) {
        const std::vector<int> kept = kept_per_block(order, model.blocks.size(), chosen.sections);
        Package package = package_at(truncated(model, kept), chosen.quality);
        if (package.file_bytes <= bytes || chosen.sections == 1) {
            if (package.file_bytes > bytes)
                fail("--target-size {}: even one component takes {} bytes", bytes,
                     package.file_bytes);
            if (choice) {
                choice->components = int(chosen.sections);
                choice->factorized = int(order.size());
                choice->quality = coded ? chosen.quality : -1;
                choice->bytes = package.file_bytes;
                choice->model_error = std::sqrt(std::max(0.0, chosen.error));
            }
            return package;
        }
        --chosen.sections;
    }
}

}  // namespace btf::factor
