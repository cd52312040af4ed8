// SPDX-License-Identifier: MIT
// FactorCodec::encode_to_size: a factorization package of at most a given size at the lowest
// error found (btf compress --target-size), the error being the eye's: the mean CIEDE2000 over a
// fixed sample of the source's values. An error in the factors' own domain (the Frobenius norm
// the factorization minimizes) chose badly: it rates noise spread thinly over every sample, as
// coarse quantization leaves, like a few large errors of the same energy, as truncation leaves,
// where the eye (and a mean of CIEDE2000) sees the spread noise first.

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "btf/core/color.h"
#include "btf/core/image.h"

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

// The sample a choice is judged on: kSampleImages images spread evenly over the (view, light)
// pairs, kSampleTexels texels of each drawn with a fixed seed (every texel when there are fewer),
// and the source's values there as CIELab.
constexpr int64_t kSampleImages = 1024;
constexpr int64_t kSampleTexels = 128;

struct EyeSample {
    std::vector<SampleIndex> at;
    std::vector<Lab> lab;
};

EyeSample eye_sample(const BtfSource& source) {
    const int w = source.width(), h = source.height();
    const int64_t texels = int64_t(w) * h;
    const Sampling& sampling = source.sampling();
    const int64_t images = sampling.num_images(), nl = sampling.num_lights();
    const int64_t count = std::min(images, kSampleImages);
    std::mt19937_64 rng(1);
    EyeSample s;
    Image image;
    for (int64_t j = 0; j < count; ++j) {
        const int64_t i = (2 * j + 1) * images / (2 * count);
        const int view = int(i / nl), light = int(i % nl);
        source.read_image(view, light, image);
        check(image.width() == w && image.height() == h && image.channels() == 3,
              "{}: image (view {}, light {}) is {}×{}×{}, expected {}×{}×3", source_name(source),
              view, light, image.width(), image.height(), image.channels(), w, h);
        for (int64_t k = 0; k < std::min(texels, kSampleTexels); ++k) {
            const int64_t t = texels <= kSampleTexels ? k : int64_t(rng() % uint64_t(texels));
            const float* v = image.data() + 3 * t;
            s.at.push_back({int(t % w), int(t / w), view, light});
            s.lab.push_back(rgb_to_lab(Rgb{v[0], v[1], v[2]}));
        }
    }
    return s;
}

// Mean CIEDE2000 of `model` against the sample.
double mean_de2000(const Model& model, const EyeSample& sample) {
    const FactorMaterial material(model);
    std::vector<Rgb> values(sample.at.size());
    material.eval_sample_batch(sample.at, values);
    double sum = 0;
    for (size_t i = 0; i < values.size(); ++i)
        sum += ciede2000(sample.lab[i], rgb_to_lab(values[i]));
    return values.empty() ? 0 : sum / double(values.size());
}

struct Candidate {
    double quality;
    size_t sections;  // component sections kept
    uint64_t bytes;   // estimated (from the full package's section sizes)
    double de2000;    // mean CIEDE2000 on the sample
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

    // For one quality: the longest prefix whose estimated size fits, judged on the sample (more
    // components at one quality leave less error: the coder stores as zeros a component whose
    // quantized form would not).
    const EyeSample sample = eye_sample(source);
    std::vector<std::pair<int, int>> order;
    std::vector<Candidate> all;
    auto candidate_at = [&](double quality) {
        const Package full = package_at(model, quality);
        const bool first = order.empty();
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
        Candidate c{quality, 0, rest_none, 0};
        uint64_t sections = 0;
        for (size_t n = 1; n <= total; ++n) {
            sections += component_bytes[n - 1];
            const uint64_t size =
                sections + rest_none +
                uint64_t(std::ceil(double(rest_full - std::min(rest_full, rest_none)) * double(n) /
                                   double(total)));
            if (size > bytes) break;
            c.sections = n;
            c.bytes = size;
        }
        if (c.sections == 0) return;
        c.de2000 = mean_de2000(
            truncated(from_package(full), kept_per_block(order, model.blocks.size(), c.sections)),
            sample);
        all.push_back(c);
    };
    auto best = [&]() -> const Candidate* {
        const Candidate* out = nullptr;
        for (const Candidate& c : all)
            if (!out || c.de2000 < out->de2000) out = &c;
        return out;
    };
    // Qualities: a coarse grid, then finer steps around the best (coded storage); other storages
    // have one "quality".
    if (coded) {
        for (double q = 0; q <= 100; q += 10) candidate_at(q);
        for (const double step : {2.0, 0.5}) {
            if (!best()) break;
            const double centre = best()->quality;
            for (int i = -4; i <= 4; ++i) {
                const double q = centre + i * step;
                if (i != 0 && q >= 0 && q <= 100) candidate_at(q);
            }
        }
    } else {
        candidate_at(kDefaultCodingQuality);
    }
    if (!best())
        fail("--target-size {}: even one component{} takes more", bytes,
             coded ? " at quality 0" : fmt::format(" in {}", to_string(result.quantization)));
    // The best choice for real. The estimate can be a few bytes short: a choice that does not fit
    // after all gives way to the next best, and should none fit, the last one keeps fewer
    // components until it does.
    Candidate chosen = *best();
    for (;;) {
        const std::vector<int> kept = kept_per_block(order, model.blocks.size(), chosen.sections);
        Package package = package_at(truncated(model, kept), chosen.quality);
        if (package.file_bytes <= bytes) {
            if (choice) {
                choice->components = int(chosen.sections);
                choice->factorized = int(order.size());
                choice->quality = coded ? chosen.quality : -1;
                choice->bytes = package.file_bytes;
                choice->de2000 = mean_de2000(from_package(package), sample);
            }
            return package;
        }
        const auto failed = std::find_if(all.begin(), all.end(), [&](const Candidate& c) {
            return c.quality == chosen.quality && c.sections == chosen.sections;
        });
        if (failed != all.end()) all.erase(failed);
        if (const Candidate* next = best()) {
            chosen = *next;
        } else if (chosen.sections > 1) {
            --chosen.sections;
        } else {
            fail("--target-size {}: even one component takes {} bytes", bytes, package.file_bytes);
        }
    }
}

}  // namespace btf::factor
