// SPDX-License-Identifier: MIT
// mlvq — multi-level vector quantization of BTFs (Havran, Filip, Myszkowski 2010, "Bidirectional
// Texture Function Compression Based on Multi-Level Vector Quantization").
//
// Every texel's apparent BRDF is resampled onto the paper's grid F_x(α, β, θv, φv)
// (parametrization.h: view on a regular (θv, φv) grid, light in "onion slices" aligned with the
// view azimuth), converted to luminance and chromaticity planes, and quantized by a hierarchy of
// code-books (codebooks.h, encoder.h): luminance as normalized 1-D, 2-D, 3-D and 4-D slices with
// scales (P1, P2, P3, P4), chromaticity as indices (C, I1, I2), merged by M; the planar index P6
// gives each texel a P4 entry and a scale.
//
// Training (§5.1.1): a Halton-sampled 1 % of the texels is inserted at the user's threshold,
// then 4 % more at 2.5 times it; the code-books are then frozen and every texel (the trained
// ones too, whose error can only shrink) takes its most similar P4 code-vector. The source is
// read twice, in bands of rows.
//
// Storage (§4.5): code-book values and scales in 8 bits (P2 scales in 16 for HDR; scales on a
// log scale, values linearly, each code-book over its own range), indices in ⌈log2 S⌉ bits.
// Sections: "codebooks", then P6 coarse to fine ("P6.3" every 8th texel per axis … "P6.0" the
// rest): a prefix with the code-books and the first P6 levels is a material whose missing texels
// copy a coarser neighbour.
//
// Evaluation: bilinear over four texels in space; per texel, the 2⁴ neighbouring grid samples of
// (ωi, ωo) reconstructed through the chain of code-books and blended multilinearly (Fig. 6),
// then converted to RGB.
//
// Stochastic filtering (btf/core/material.h): a shading point draws one of the 4 texels × 2 θv ×
// 2 φv view nodes of that blend with probability equal to its weight, and its term reads that
// one chain, bilinear in (α, β) within its M entry; its mean is eval() for YCbCr colour.
// Sampling draws from the term's M entry alone, as sample() does from a mixture component.
//
// Parameters: schema() below declares each once (the default is the Options initializer in
// mlvq.h and encoder.h); `btf codecs` lists them. Notes: the mse threshold is in plane units
// (Y ≈ reflectance), the mssim one a 98th percentile of 1 − SSIM; each luminance level below P4
// takes level-factor times the threshold above (the paper's constant is 0.4; 1 keeps the same
// bound with far smaller code-books, see encoder.h); I1 and C take level-factor and its square
// times chroma-threshold; the grid is §6's, the training §5.1.1's.

#include "btf/codecs/mlvq/mlvq.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <set>
#include <tuple>
#if defined(__AVX2__) || defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "btf/codecs/factor/model.h"
#include "btf/codecs/param_schema.h"
#include "btf/core/btf_lookup.h"
#include "btf/core/pick_lanes.h"
#include "btf/util/error.h"
#include "btf/util/json_fields.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

namespace btf {

namespace mlvq {

namespace {

constexpr const char* kName = "mlvq";

const ParamSchema<Options>& schema() {
    static const ParamSchema<Options> schema = [] {
        ParamSchema<Options> s{kName};
        s.number(
             "threshold", [](auto& o) -> auto& { return o.encoder.threshold; }, 0, 1e6,
             "largest error of a texel's F_x at P4: mse in plane units (Y ~ reflectance), or "
             "the 98th percentile of 1 - SSIM")
            .number(
                "level-factor", [](auto& o) -> auto& { return o.encoder.level_factor; }, 1e-6, 1,
                "mse: threshold ratio between successive luminance code-books (the paper: 0.4)")
            .number(
                "chroma-threshold", [](auto& o) -> auto& { return o.encoder.threshold_i2; }, 0, 1e6,
                "mse threshold of I2 (I1, C: times level-factor, its square)")
            .choice(
                "measure", [](auto& o) -> auto& { return o.encoder.measure; },
                std::vector<std::pair<std::string, Measure>>{{"mse", Measure::mse},
                                                             {"mssim", Measure::mssim}},
                "similarity measure: mse or mssim")
            .choice("colour", &Options::colour,
                    std::vector<std::pair<std::string, std::optional<ColourModel>>>{
                        {"auto", std::nullopt},
                        {"ycbcr", ColourModel::kYCbCr},
                        {"logluv", ColourModel::kLogLuv}},
                    "auto (ycbcr for LDR, logluv for HDR), ycbcr or logluv")
            .integer(
                "n-alpha", [](auto& o) -> auto& { return o.encoder.grid.n_alpha; }, 3,
                MlvqGrid::kMaxAxis, "light slices (alpha)")
            .integer(
                "n-beta", [](auto& o) -> auto& { return o.encoder.grid.n_beta; }, 3,
                MlvqGrid::kMaxAxis, "samples along a slice (beta), poles included")
            .integer(
                "n-theta-v", [](auto& o) -> auto& { return o.encoder.grid.n_theta_v; }, 2,
                MlvqGrid::kMaxAxis, "view elevations 0-90 degrees")
            .integer(
                "n-phi-v", [](auto& o) -> auto& { return o.encoder.grid.n_phi_v; }, 1,
                MlvqGrid::kMaxAxis, "view azimuths (1: isotropic)")
            .number("first", &Options::first_fraction, 0, 1,
                    "training step 1: fraction of texels inserted at the threshold")
            .number("second", &Options::second_fraction, 0, 1,
                    "training step 2: fraction of texels inserted at growth x threshold")
            .number("growth", &Options::growth, 1, 1e6, "threshold factor of training step 2")
            .then([](Options& o) {
                EncoderOptions& e = o.encoder;
                e.threshold_i1 = e.threshold_i2 * e.level_factor;
                e.threshold_c = e.threshold_i2 * e.level_factor * e.level_factor;
                e.grid.validate();
            });
        return s;
    }();
    return schema;
}

double now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

double radical_inverse(uint64_t i, uint64_t base) {
    double result = 0, f = 1.0 / double(base);
    while (i) {
        result += f * double(i % base);
        i /= base;
        f /= double(base);
    }
    return result;
}

// The first `count` distinct texels of the 2-D Halton sequence (bases 2, 3).
std::vector<int64_t> halton_texels(int width, int height, int64_t count) {
    std::vector<int64_t> out;
    std::vector<bool> taken(size_t(width) * height, false);
    count = std::min<int64_t>(count, int64_t(width) * height);
    for (uint64_t i = 1; int64_t(out.size()) < count; ++i) {
        const int x = std::min(width - 1, int(radical_inverse(i, 2) * width));
        const int y = std::min(height - 1, int(radical_inverse(i, 3) * height));
        const int64_t t = int64_t(y) * width + x;
        if (taken[size_t(t)]) continue;
        taken[size_t(t)] = true;
        out.push_back(t);
    }
    return out;
}

// RGB F_x (plane-major) → (Y, c₁, c₂) in place.
void to_planes_in_place(ColourModel colour, float* f, int64_t n) {
    for (int64_t s = 0; s < n; ++s) {
        const std::array<float, 3> p = to_planes(colour, {f[s], f[n + s], f[2 * n + s]});
        f[s] = p[0];
        f[n + s] = p[1];
        f[2 * n + s] = p[2];
    }
}

// Rows per band so that raw and resampled texels of a band stay within the budget.
int band_rows(const BtfSource& source, int64_t per_texel_resampled, int64_t memory) {
    const int64_t per_row =
        SourceTexels::bytes(source.num_views(), source.num_lights(), source.width()) +
        int64_t(source.width()) * per_texel_resampled * int64_t(sizeof(float));
    return int(std::clamp<int64_t>(memory / std::max<int64_t>(per_row, 1), 1, source.height()));
}

}  // namespace

Options parse_options(const Params& params) {
    return schema().parse(params);
}

std::pair<Codebooks, std::vector<TexelIndex>> encode_shared(
    std::span<const BtfSource* const> sources, const Options& options, Progress& progress,
    EncodeReport* report) {
    check(!sources.empty(), "mlvq: no material to encode");
    EncoderOptions eo = options.encoder;
    bool hdr = false;
    for (const BtfSource* source : sources) {
        check(source->num_texels() > 0 && source->num_views() > 0 && source->num_lights() > 0,
              "{}: mlvq: empty BTF", factor::source_name(*source));
        hdr = hdr || source->info().hdr;
    }
    eo.colour = options.colour.value_or(hdr ? ColourModel::kLogLuv : ColourModel::kYCbCr);
    Encoder encoder(eo);
    const int64_t n4 = eo.grid.samples(), length = 3 * n4;
    EncodeReport stats;

    // Per material: its resampler, training texels (Halton order, step 1 first) and where they
    // sit in the training array.
    struct Part {
        const BtfSource* source;
        std::unique_ptr<Resampler> resampler;
        std::vector<int64_t> trained, slot;
        int64_t first = 0;
        int rows = 1;
        std::vector<float> training;
        std::vector<IndexScale> p6;
    };
    std::vector<Part> parts;
    uint64_t read_units = 0;
    for (const BtfSource* source : sources) {
        Part part;
        part.source = source;
        part.resampler = std::make_unique<Resampler>(eo.grid, source->sampling());
        const int64_t texels = source->num_texels();
        part.first = std::max<int64_t>(1, std::llround(options.first_fraction * texels));
        const int64_t second = std::llround(options.second_fraction * texels);
        part.trained = halton_texels(source->width(), source->height(), part.first + second);
        part.slot.assign(size_t(texels), -1);
        for (size_t i = 0; i < part.trained.size(); ++i)
            part.slot[size_t(part.trained[i])] = int64_t(i);
        part.rows = band_rows(*source, length, options.memory_bytes);
        part.p6.resize(size_t(texels));
        read_units += uint64_t(source->num_views()) * source->num_lights() *
                      uint64_t((source->height() + part.rows - 1) / part.rows);
        stats.texels += texels;
        parts.push_back(std::move(part));
    }

    double t0 = now();
    progress.begin("mlvq: reading training texels", read_units);
    for (Part& part : parts) {
        const BtfSource& source = *part.source;
        const int width = source.width();
        part.training.resize(part.trained.size() * size_t(length));
        for (int y0 = 0; y0 < source.height(); y0 += part.rows) {
            const int n = std::min(part.rows, source.height() - y0);
            const SourceTexels raw = read_rows(source, y0, n, progress);
            parallel_for(0, int64_t(n) * width, [&](int64_t local) {
                const int64_t s = part.slot[size_t(int64_t(y0) * width + local)];
                if (s < 0) return;
                float* f = part.training.data() + size_t(s) * length;
                part.resampler->resample(raw, local, 1, f);
                to_planes_in_place(eo.colour, f, n4);
            });
        }
    }
    progress.finish();
    stats.seconds_reading = now() - t0;

    // Steps 1 and 2 over all materials: the code-books describe all of them.
    t0 = now();
    uint64_t total = 0;
    for (const Part& part : parts) total += part.trained.size();
    progress.begin("mlvq: training code-books", total);
    for (int step = 0; step < 2; ++step) {
        if (step == 1) encoder.scale_thresholds(options.growth);
        for (Part& part : parts) {
            const size_t begin = step == 0 ? 0 : size_t(part.first);
            const size_t end = step == 0
                                   ? size_t(std::min<int64_t>(part.first, part.trained.size()))
                                   : part.trained.size();
            for (size_t i = begin; i < end; ++i) {
                part.p6[size_t(part.trained[i])] = encoder.insert(
                    std::span<const float>(part.training.data() + i * length, size_t(length)));
                progress.advance();
            }
        }
    }
    progress.finish();
    for (Part& part : parts) {
        part.training = {};
        stats.trained += int64_t(part.trained.size());
    }
    encoder.freeze();
    stats.seconds_training = now() - t0;

    t0 = now();
    progress.begin("mlvq: encoding texels", read_units);
    std::vector<float> band;
    for (Part& part : parts) {
        const BtfSource& source = *part.source;
        const int width = source.width();
        for (int y0 = 0; y0 < source.height(); y0 += part.rows) {
            const int n = std::min(part.rows, source.height() - y0);
            const SourceTexels raw = read_rows(source, y0, n, progress);
            band.resize(size_t(n) * width * size_t(length));
            part.resampler->resample(raw, band);
            parallel_for(0, int64_t(n) * width, [&](int64_t t) {
                to_planes_in_place(eo.colour, band.data() + size_t(t) * length, n4);
            });
            // Every texel, the trained ones included, takes its most similar P4 entry of the
            // final code-books: at least as close as the entry its insertion produced, and
            // identical texels get identical entries.
            const std::vector<IndexScale> found = encoder.nearest(band);
            std::copy(found.begin(), found.end(), part.p6.begin() + int64_t(y0) * width);
        }
    }
    progress.finish();
    stats.seconds_frozen = now() - t0;
    if (report) *report = stats;

    std::vector<TexelIndex> indices;
    for (Part& part : parts) {
        const BtfSource& source = *part.source;
        TexelIndex index;
        index.name = source.info().path.empty() ? std::string(source.info().format)
                                                : source.info().path.filename().string();
        index.width = source.width();
        index.height = source.height();
        index.sampling = source.sampling();
        index.hdr = source.info().hdr;
        index.p6 = std::move(part.p6);
        indices.push_back(std::move(index));
    }
    return {encoder.codebooks(), std::move(indices)};
}

std::pair<Codebooks, TexelIndex> encode(const BtfSource& source, const Options& options,
                                        Progress& progress, EncodeReport* report) {
    const BtfSource* sources[] = {&source};
    auto [books, indices] = encode_shared(sources, options, progress, report);
    return {std::move(books), std::move(indices[0])};
}

namespace {

// The batches run their queries in blocks of kBlock (the lanes of lookup_views())
// through a software pipeline of `Stages` stages: iteration j runs stage 0 of block j, stage 1
// of block j − 1, …, and each stage prefetches what the block's next stage reads (P6, the fused
// view, the M entry), which then has a whole iteration of every stage's arithmetic to arrive.
// A query's own operations and their order are those of the one-query path (eval(), or the
// ShadingPoint's), so the results are the same bit for bit. `stage(k, first, count, slot)` runs
// stage k of queries [first, first + count), whose state is at ring slot `slot` (of Stages).
// With `query_stage`, the last two stages run after the others query by query in turn instead:
// `query_stage(k, query, slot, i)` for query i of its block, so that one query's prefetches
// alternate with another's arithmetic (a burst of more prefetches than the core has miss
// buffers stalls the instructions behind it).
constexpr size_t kBlock = 4;
template <size_t Stages, typename Stage, typename QueryStage>
void pipeline(size_t n, Stage&& stage, QueryStage&& query_stage, bool by_query = true) {
    static_assert(Stages >= 2);
    const size_t blocks = (n + kBlock - 1) / kBlock;
    auto count = [&](size_t b) { return std::min(kBlock, n - b * kBlock); };
    const size_t block_stages = by_query ? Stages - 2 : Stages;
    for (size_t j = 0; j < blocks + Stages - 1; ++j) {
        for (size_t k = 0; k < block_stages; ++k)
            if (j >= k && j - k < blocks)
                stage(k, (j - k) * kBlock, count(j - k), (j - k) % Stages);
        if (!by_query) continue;
        for (size_t i = 0; i < kBlock; ++i)
            for (size_t k = Stages - 2; k < Stages; ++k)
                if (j >= k && j - k < blocks && i < count(j - k))
                    query_stage(k, (j - k) * kBlock + i, (j - k) % Stages, i);
    }
}
template <size_t Stages, typename Stage>
void pipeline(size_t n, Stage&& stage) {
    pipeline<Stages>(
        n, stage, [](size_t, size_t, size_t, size_t) {}, false);
}

// Hints every cache line of [begin, end].
void prefetch_range(const void* begin, const void* end) {
    const uintptr_t line = 64, last = reinterpret_cast<uintptr_t>(end) | (line - 1);
    for (uintptr_t a = reinterpret_cast<uintptr_t>(begin) & ~(line - 1); a <= last; a += line)
        __builtin_prefetch(reinterpret_cast<const void*>(a));
}

// Hints the lines of α rows i and i + 1 of entry m's luminance halves, what a draw of β reads
// (through the second row's whole window, which invert_columns() loads).
void prefetch_luminance_rows(const DecodedBooks& d, uint32_t m, int i) {
    const char* row = static_cast<const char*>(d.luminance_row(m, i));
    prefetch_range(row,
                   row + sizeof(uint16_t) * size_t(d.grid().n_beta) + DecodedBooks::kRowWindow - 1);
}

// A number into [0, 1): ShadingPoint's clamp of the filter number, and of sampling's (ξ1, ξ2)
// (NaN to 0: a NaN would reach an index).
double filter_number(double u) {
    if (!(u >= 0)) u = 0;  // NaN too
    return std::min(u, 0x1.fffffffffffffp-1);
}

TexelCorners texel_corners(const Uv& uv, int width, int height) {
    const WrapLerp lx = wrap_lerp(uv.u, width), ly = wrap_lerp(uv.v, height);
    const int64_t r0 = int64_t(ly.i0) * width, r1 = int64_t(ly.i1) * width;
    return {{r0 + lx.i0, r0 + lx.i1, r1 + lx.i0, r1 + lx.i1},
            {(1 - lx.t) * (1 - ly.t), lx.t * (1 - ly.t), (1 - lx.t) * ly.t, lx.t * ly.t}};
}

}  // namespace

// ---- evaluation ---------------------------------------------------------------------------------

MlvqMaterial::MlvqMaterial(std::shared_ptr<const Codebooks> books, TexelIndex index,
                           std::shared_ptr<const DecodedBooks> decoded)
    : m_books(std::move(books)), m_index(std::move(index)), m_decoded(std::move(decoded)) {
    check(m_books != nullptr, "mlvq material without code-books");
    check(int64_t(m_index.p6.size()) == int64_t(m_index.width) * m_index.height,
          "mlvq material: {} P6 entries for {}×{} texels", m_index.p6.size(), m_index.width,
          m_index.height);
    for (const IndexScale& e : m_index.p6)
        check(e.index < m_books->size_p4(), "mlvq material: P6 points to P4 {} of {}", e.index,
              m_books->size_p4());
    if (!m_decoded) m_decoded = std::make_shared<const DecodedBooks>(*m_books);
    check(m_decoded->size_m() == m_books->size_m(),
          "mlvq material: decoded code-books of {} M entries for code-books of {}",
          m_decoded->size_m(), m_books->size_m());
}

// One query's 16 light functions: for each of 4 texels × 2 φv × 2 θv the M entry and its samples,
// its luminance scale (weight · c_P6 · c_P4 · c_P3) and its chromaticity weight, and the offsets
// and weights of the 2 × 2 (α, β) corners within an entry.
struct MlvqMaterial::Gathered {
    int count = 0;
    uint32_t index[16];  ///< M entries
    const DecodedBooks::Sample* entry[16];
    float y_scale[16], c_weight[16];
    DecodedBooks::Corners corners;

    // Hints the cache line the corners of entry c lie on (one tile: decoded.h).
    void prefetch(int c) const { __builtin_prefetch(entry[c] + corners.off[0]); }
};

void MlvqMaterial::gather(const TexelCorners& corners, const MlvqWeights& w, Gathered& out) const {
    // Always all 16 (texel, φv, θv) corners, without branches on zero weights (a corner of
    // weight 0 adds 0; its entries exist all the same).
    const DecodedBooks& d = *m_decoded;
    const int n_theta = d.grid().n_theta_v;
    int offset[4];
    float weight[4];
    for (int p = 0; p < 2; ++p)
        for (int t = 0; t < 2; ++t) {
            offset[p * 2 + t] = w.phi_v.index[p] * n_theta + w.theta_v.index[t];
            weight[p * 2 + t] = w.phi_v.weight[p] * w.theta_v.weight[t];
        }
    for (int k = 0; k < 4; ++k) {
        const IndexScale& e6 = m_index.p6[size_t(corners.texel[k])];
        const IndexScale* views = d.views(e6.index);
        for (int j = 0; j < 4; ++j) {
            const IndexScale& v = views[offset[j]];
            const float wt = corners.weight[k] * weight[j];
            out.index[k * 4 + j] = v.index;
            out.entry[k * 4 + j] = d.entry(v.index);
            out.y_scale[k * 4 + j] = wt * e6.scale * v.scale;
            out.c_weight[k * 4 + j] = wt;
        }
    }
    out.count = 16;
    out.corners = DecodedBooks::Corners(d.grid(), w);
}

// Prefetches what gather() will read of P4 ∘ P3 for the four texels (their P6 entries should be
// in cache or on their way: the batch pipelines prefetch them one stage earlier).
void MlvqMaterial::prefetch_views(const TexelCorners& corners, const MlvqWeights& w) const {
    const MlvqGrid& g = m_decoded->grid();
    for (int k = 0; k < 4; ++k) {
        const IndexScale* v = m_decoded->views(m_index.p6[size_t(corners.texel[k])].index);
        for (int p = 0; p < 2; ++p)
            __builtin_prefetch(v + w.phi_v.index[p] * g.n_theta_v + w.theta_v.index[0]);
    }
}

std::array<float, 3> MlvqMaterial::combine(const Gathered& g) const {
    return m_decoded->blend(g.entry, g.y_scale, g.c_weight, g.count, g.corners);
}

std::array<float, 3> MlvqMaterial::planes(int64_t texel, const MlvqWeights& w) const {
    Gathered g;
    gather({{texel, texel, texel, texel}, {1, 0, 0, 0}}, w, g);
    return combine(g);
}

Rgb MlvqMaterial::eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    return eval_weights(uv, lookup(m_books->grid, wi, wo));
}

Rgb MlvqMaterial::eval_weights(const Uv& uv, const MlvqWeights& w) const {
    Gathered g;
    gather(texel_corners(uv, m_index.width, m_index.height), w, g);
    const std::array<float, 3> p = combine(g);
    return from_planes(m_books->colour, p[0], p[1], p[2]);
}

void MlvqMaterial::eval_batch(std::span<const Query> queries, std::span<Rgb> out) const {
    if (queries.size() != out.size())
        fail("eval_batch: {} queries but {} outputs", queries.size(), out.size());
    // Random queries miss the cache at every level of P6 → P4 ∘ P3 → M: the levels are the
    // stages of pipeline(), the M entries (16 prefetches a query) and the blend query by query.
    constexpr size_t kStages = 4;
    struct State {
        MlvqWeights w;
        TexelCorners corners;
        Gathered g;
    };
    State ring[kStages][kBlock];
    const MlvqGrid& grid = m_books->grid;
    MlvqWeights carried;  // the last query's weights, for a run that goes on into the next block
    auto same = [](const Vec3& a, const Vec3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; };
    auto stage = [&](size_t k, size_t first, size_t count, size_t slot) {
        State* s = ring[slot];
        if (k == 1) {  // P4 ∘ P3
            for (size_t i = 0; i < count; ++i) prefetch_views(s[i].corners, s[i].w);
            return;
        }
        // Directions (one lookup per run of equal ωi, ωo) and texels; P6.
        const Query* q = queries.data() + first;
        Vec3 wi[kBlock], wo[kBlock];
        MlvqWeights looked_up[kBlock];
        int run[kBlock];
        size_t runs = 0;
        for (size_t i = 0; i < count; ++i) {
            const Query* previous = first + i > 0 ? q + i - 1 : nullptr;
            if (!previous || !same(q[i].wi, previous->wi) || !same(q[i].wo, previous->wo)) {
                wi[runs] = q[i].wi;
                wo[runs] = q[i].wo;
                ++runs;
            }
            run[i] = int(runs) - 1;  // −1: the run goes on from the previous block
        }
        lookup(grid, wi, wo, runs, looked_up);
        for (size_t i = 0; i < count; ++i) {
            s[i].w = run[i] >= 0 ? looked_up[run[i]] : carried;
            s[i].corners = texel_corners(q[i].uv, m_index.width, m_index.height);
            for (int c = 0; c < 4; ++c)
                __builtin_prefetch(&m_index.p6[size_t(s[i].corners.texel[c])]);
        }
        carried = s[count - 1].w;
    };
    auto query_stage = [&](size_t k, size_t query, size_t slot, size_t i) {
        State& s = ring[slot][i];
        if (k == 2) {  // the M entries
            gather(s.corners, s.w, s.g);
            for (int c = 0; c < s.g.count; ++c) s.g.prefetch(c);
        } else {
            const std::array<float, 3> p = combine(s.g);
            out[query] = from_planes(m_books->colour, p[0], p[1], p[2]);
        }
    };
    pipeline<kStages>(queries.size(), stage, query_stage);
}

Rgb MlvqMaterial::eval_sample(int x, int y, int view, int light) const {
    if (x < 0 || x >= width() || y < 0 || y >= height() || view < 0 ||
        view >= m_index.sampling.num_views() || light < 0 || light >= m_index.sampling.num_lights())
        fail("eval_sample: ({}, {}, view {}, light {}) is outside the material", x, y, view, light);
    const MlvqWeights w = lookup(m_books->grid, m_index.sampling.lights.vector(light),
                                 m_index.sampling.views.vector(view));
    const std::array<float, 3> p = planes(int64_t(y) * width() + x, w);
    return from_planes(m_books->colour, p[0], p[1], p[2]);
}

Package to_package(const Codebooks& books, const std::vector<TexelIndex>& materials,
                   const Options& o) {
    check(!materials.empty(), "mlvq: a package needs a material");
    Package package;
    auto& h = package.header;
    h["codec"] = kName;
    h["params"] = schema().to_json(o);
    // The first material's extent and sampling describe the package for generic tools.
    const TexelIndex& first = materials.front();
    h["width"] = first.width;
    h["height"] = first.height;
    h["views"] = factor::directions_json(first.sampling.views);
    h["lights"] = factor::directions_json(first.sampling.lights);
    bool hdr = false;
    for (const TexelIndex& m : materials) hdr = hdr || m.hdr;
    h["hdr"] = first.hdr;
    h["raw_bytes_8bit"] = int64_t(first.width) * first.height * first.sampling.num_images() * 3;
    write_codebooks(books, hdr, h, package.sections);

    // P6 sections coarse to fine, the materials interleaved level by level.
    nlohmann::json list = nlohmann::json::array();
    std::vector<std::vector<PackageSection>> p6(materials.size());
    int64_t texels = 0;
    for (size_t k = 0; k < materials.size(); ++k) {
        const TexelIndex& m = materials[k];
        nlohmann::json entry;
        const std::string prefix = materials.size() == 1 ? "" : fmt::format("m{}.", k);
        entry["name"] = m.name;
        entry["prefix"] = prefix;
        entry["width"] = m.width;
        entry["height"] = m.height;
        entry["views"] = factor::directions_json(m.sampling.views);
        entry["lights"] = factor::directions_json(m.sampling.lights);
        entry["hdr"] = m.hdr;
        write_texel_index(m, books.size_p4(), prefix, entry, p6[k]);
        list.push_back(entry);
        texels += int64_t(m.width) * m.height;
    }
    for (size_t level = 0;; ++level) {
        bool any = false;
        for (auto& sections : p6)
            if (level < sections.size()) {
                package.sections.push_back(std::move(sections[level]));
                any = true;
            }
        if (!any) break;
    }
    h["materials"] = list;
    const StorageSizes sizes = storage_sizes(books, texels, hdr);
    h["storage_bytes"] = sizes.bytes;  // C.R.1 … C.R.4 representations (all materials)
    nlohmann::json table = nlohmann::json::array();
    for (const auto& [name, entries, bytes] : sizes.books)
        table.push_back({{"name", name}, {"entries", entries}, {"bytes", bytes}});
    h["codebook_table"] = table;
    package.declared_sections = static_cast<int>(package.sections.size());
    return package;
}

std::vector<std::unique_ptr<MlvqMaterial>> open_all(const Package& package) {
    const std::string what = "package (mlvq)";
    if (package.codec() != kName)
        fail("package of codec '{}' opened as {}", package.codec(), kName);
    return read_package_fields(what, [&] {
        auto books = std::make_shared<const Codebooks>(read_codebooks(package));
        std::shared_ptr<const DecodedBooks> decoded;
        std::vector<std::unique_ptr<MlvqMaterial>> out;
        const nlohmann::json& list = package.header.at("materials");
        if (!list.is_array() || list.empty()) fail("no materials");
        // The package-level extent and sampling are the first material's (generic tools read
        // them); they must not say something else.
        for (const char* key : {"width", "height", "views", "lights"})
            if (package.header.at(key) != list[0].at(key))
                fail("'{}' differs from the first material's", key);
        std::set<std::string> known = {"codebooks"};
        std::string missing;
        for (const nlohmann::json& m : list) {
            TexelIndex index;
            index.name = m.at("name").get<std::string>();
            std::tie(index.width, index.height) = json_fields::extent(m);
            index.sampling.views = factor::directions_from_json(m.at("views"));
            index.sampling.lights = factor::directions_from_json(m.at("lights"));
            index.hdr = m.value("hdr", false);
            const std::string prefix = m.at("prefix").get<std::string>();
            const int levels = texel_index_levels(index.width, index.height);
            for (int level = 0; level < levels; ++level)
                known.insert(fmt::format("{}P6.{}", prefix, level));
            if (!package.find(fmt::format("{}P6.{}", prefix, levels - 1))) {
                // Not yet received (a prefix of the stream).
                if (missing.empty()) missing = fmt::format("{}P6.{}", prefix, levels - 1);
                continue;
            }
            index.p6 =
                read_texel_index(package, m, prefix, index.width, index.height, books->size_p4());
            if (!decoded) decoded = std::make_shared<const DecodedBooks>(*books);
            out.push_back(std::make_unique<MlvqMaterial>(books, std::move(index), decoded));
        }
        for (const PackageSection& s : package.sections)
            if (!known.count(s.name)) fail("unknown section '{}'", s.name);
        if (out.empty()) fail("section '{}' is missing", missing);
        return out;
    });
}

// ---- importance sampling and albedo -------------------------------------------------------------

// A query's light function as a mixture of the 16 gathered M entries (weights y_scale, each an
// entry bilinear in (α, u)) with their masses (weight × the entry's integral, index units).
struct MlvqMaterial::Mixture {
    Gathered g;
    double mass[16];
    double total = 0;
    ViewLookup view;

    // Masses are in sample-index units: one unit is π/(nα − 1) · 2/(nβ − 1) of solid angle.
    static double cell(const MlvqGrid& g) { return kPi / (g.n_alpha - 1) * 2.0 / (g.n_beta - 1); }
};

namespace {

// Draws whose inverse CDFs are found together (inverse_cdfs()): each step of the inversion is
// issued for all of them, so that their chains of dependent instructions overlap. One draw's
// chain (running sums, segment, square root, division) is longer than the core looks ahead
// past, and draws one after another would wait out each other's latencies.
constexpr int kDraws = 4;

// The fractional sample index within segment i (end values a, b; the cumulative mass `low` at
// its start) where the mass reaches `target`: within a segment the mass up to t ∈ [0, 1] is
// a t + (b − a) t² / 2, and t the root 2 r / (a + √(a² + 2 (b − a) r)) of a t + (b − a) t² / 2
// = r, a form that stays exact as b → a (it is r / a there). In floats (a and b are) and without
// branches: the draws are random, and a branch on them would mispredict.
double invert_segment(int i, float low, float a, float b, double target) {
    const float segment = 0.5f * (a + b);
    // Into [0, segment]; NaN (from a NaN target) to 0.
    float r = float(target - double(low));
    r = std::min(r > 0 ? r : 0.0f, segment);
    const float denominator = a + std::sqrt(std::max(0.0f, a * a + 2 * (b - a) * r));
    // A segment of no mass (or a crafted a < 0) has no root to find: its middle, or its start.
    const float x = denominator > 0 ? 2 * r / denominator : segment > 0 ? 0.0f : 0.5f;
    // Into [0, 1], NaN (a share of 0 / 0, a crafted sample) to 0: the caller truncates it to
    // an index.
    return i + double(x > 0 ? std::min(x, 1.0f) : 0.0f);
}

#ifdef __AVX512F__
// invert_segment() for the kDraws draws of the arrays, in the lanes of vectors where the CPU
// has them (the same operations lane by lane).
void invert_segments(const int* i, const float* low, const float* a, const float* b,
                     const double* target, double* out) {
#if defined(__AVX2__) && defined(__FMA__)
    static_assert(kDraws == 4);
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
    const __m128 va = _mm_loadu_ps(a), vb = _mm_loadu_ps(b);
    const __m128 segment = _mm_mul_ps(_mm_set1_ps(0.5f), _mm_add_ps(va, vb));
    __m128 r =
        _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_loadu_pd(target), _mm256_cvtps_pd(_mm_loadu_ps(low))));
    // As std::min(max(r, 0), segment): minps and maxps give their second operand for a NaN.
    r = _mm_min_ps(segment, _mm_max_ps(r, zero));
    const __m128 twice_slope = _mm_add_ps(_mm_sub_ps(vb, va), _mm_sub_ps(vb, va));
    const __m128 discriminant = _mm_max_ps(_mm_fmadd_ps(twice_slope, r, _mm_mul_ps(va, va)), zero);
    const __m128 denominator = _mm_add_ps(va, _mm_sqrt_ps(discriminant));
    const __m128 root = _mm_div_ps(_mm_add_ps(r, r), denominator);
    const __m128 fallback = _mm_andnot_ps(_mm_cmpgt_ps(segment, zero), _mm_set1_ps(0.5f));
    __m128 x = _mm_blendv_ps(fallback, root, _mm_cmpgt_ps(denominator, zero));
    x = _mm_and_ps(_mm_cmpgt_ps(x, zero), _mm_min_ps(x, one));
    alignas(16) float t[kDraws];
    _mm_store_ps(t, x);
    for (int k = 0; k < kDraws; ++k) out[k] = i[k] + double(t[k]);
#else
    for (int k = 0; k < kDraws; ++k) out[k] = invert_segment(i[k], low[k], a[k], b[k], target[k]);
#endif
}
#endif

// The segment of a density linear between samples v[0 … n−1] (unit spacing) where the mass
// reaches `target` (in [0, Σ trapezoids)), and the mass below it: the number of segments whose
// cumulative mass the target reaches (the last one takes any excess), counted over all of them
// rather than found by a loop that stops there (the draws are random: that loop's exit would
// mispredict once per draw).
template <typename Value>
int find_segment(Value v, int n, double target, double& low) {
    int i = 0;
    double cumulative = 0, a = v(0);
    low = 0;
    for (int k = 0; k + 2 < n; ++k) {
        const double b = v(k + 1);
        cumulative += 0.5 * (a + b);
        const bool below = cumulative <= target;
        i += below;
        low = below ? cumulative : low;
        a = b;
    }
    return i;
}

#ifdef __AVX512F__
constexpr int kRowLanes = 16;  ///< samples of a row that one vector holds

// The shuffles below are the zero-masking forms with every lane kept: the same instruction, and
// GCC 12 warns of an uninitialized variable inside the unmasked forms where they are inlined.
constexpr __mmask16 kAllLanes = 0xffff;

// Lane i of the result is v[i + K] (0 from 16 − K).
template <int K>
__m512 lanes_down(__m512 v, __m512 zero) {
    return _mm512_castsi512_ps(
        _mm512_maskz_alignr_epi32(kAllLanes, _mm512_castps_si512(zero), _mm512_castps_si512(v), K));
}
// Lane i of the result is v[i − K] (0 below K).
template <int K>
__m512 lanes_up(__m512 v, __m512 zero) {
    return _mm512_castsi512_ps(_mm512_maskz_alignr_epi32(kAllLanes, _mm512_castps_si512(v),
                                                         _mm512_castps_si512(zero), kRowLanes - K));
}
float lane(__m512 v, int i) {
    return _mm512_cvtss_f32(_mm512_maskz_permutexvar_ps(kAllLanes, _mm512_set1_epi32(i), v));
}

// The fractional indices at which the densities in the lanes of v[k] (n ≤ 16 samples each)
// reach target[k], k < kDraws (float sums): find_segment() by vectors, the trapezoids at once,
// their running sums in four shifted additions and the segment as the count of sums the
// target reaches (one mask).
// (Inlined, and its loops unrolled, so that the vectors stay in registers.)
[[gnu::always_inline]] inline void invert_linear_lanes(const __m512* v, int n, const double* target,
                                                       double* out) {
    const __m512 zero = _mm512_setzero_ps(), half = _mm512_set1_ps(0.5f);
    const __mmask16 segments = __mmask16((1u << (n - 1)) - 1);
    __m512 c[kDraws];
#pragma GCC unroll 4
    for (int k = 0; k < kDraws; ++k)
        c[k] = _mm512_maskz_mul_ps(segments, half, _mm512_add_ps(v[k], lanes_down<1>(v[k], zero)));
#pragma GCC unroll 4
    for (int k = 0; k < kDraws; ++k) c[k] = _mm512_add_ps(c[k], lanes_up<1>(c[k], zero));
#pragma GCC unroll 4
    for (int k = 0; k < kDraws; ++k) c[k] = _mm512_add_ps(c[k], lanes_up<2>(c[k], zero));
#pragma GCC unroll 4
    for (int k = 0; k < kDraws; ++k) c[k] = _mm512_add_ps(c[k], lanes_up<4>(c[k], zero));
#pragma GCC unroll 4
    for (int k = 0; k < kDraws; ++k) c[k] = _mm512_add_ps(c[k], lanes_up<8>(c[k], zero));
    int i[kDraws];
    float low[kDraws], a[kDraws], b[kDraws];
#pragma GCC unroll 4
    for (int k = 0; k < kDraws; ++k) {
        const __mmask16 below = _mm512_mask_cmp_ps_mask(
            segments >> 1, c[k], _mm512_set1_ps(float(target[k])), _CMP_LE_OQ);
        i[k] = std::popcount(unsigned(below));
        low[k] = lane(lanes_up<1>(c[k], zero), i[k]);  // the sum below segment i, 0 for i = 0
        a[k] = lane(v[k], i[k]);
        b[k] = lane(v[k], i[k] + 1);
    }
    invert_segments(i, low, a, b, target, out);
}
#endif

// The fractional index at which a density linear between samples v[0 … n−1] reaches `target`.
template <typename Value>
double invert_linear_loop(Value v, int n, double target) {
    double low;
    const int i = find_segment(v, n, target, low);
    return invert_segment(i, float(low), float(v(i)), float(v(i + 1)), target);
}

// The fractional α indices at which the row masses rows[k][0 … n − 1] (floats) reach
// target[k], for the draws k < count ≤ kDraws whose rows are not null.
void invert_rows(const float* const* rows, int count, int n, const double* target, double* out) {
#ifdef __AVX512F__
    if (n <= kRowLanes) {
        const __mmask16 mask = __mmask16((1u << n) - 1);
        __m512 v[kDraws];
        double t[kDraws];
#pragma GCC unroll 4
        for (int k = 0; k < kDraws; ++k) {
            const bool drawn = k < count && rows[k];
            v[k] = drawn ? _mm512_maskz_loadu_ps(mask, rows[k]) : _mm512_setzero_ps();
            t[k] = drawn ? target[k] : 0;
        }
        invert_linear_lanes(v, n, t, out);
        return;
    }
#endif
    for (int k = 0; k < count; ++k)
        if (rows[k])
            out[k] = invert_linear_loop([&](int i) { return double(rows[k][i]); }, n, target[k]);
}

// A β draw: the column t0 · (row i0) + t1 · (row i0 + 1) of an entry's luminance (its sampling
// record's halves from row i0 on: DecodedBooks::luminance_row()), and the mass to reach along it.
struct ColumnDraw {
    const void* rows = nullptr;  ///< null: nothing to draw
    float t0 = 0, t1 = 0;
    double target = 0;
};

// The fractional β indices at which the draws' columns reach their targets (count ≤ kDraws).
void invert_columns(int n, const ColumnDraw* draws, int count, double* out) {
#ifdef __AVX512F__
    if (n <= kRowLanes) {
        // A row's n halves from one load of 16 (the record holds that window of every row),
        // widened in n lanes.
        static_assert(DecodedBooks::kRowWindow == sizeof(__m256i));
        const __mmask16 lanes = __mmask16((1u << n) - 1);
        auto row = [lanes](const void* halves) {
            return _mm512_maskz_cvtph_ps(lanes,
                                         _mm256_loadu_si256(static_cast<const __m256i*>(halves)));
        };
        __m512 column[kDraws];
        double target[kDraws];
#pragma GCC unroll 4
        for (int k = 0; k < kDraws; ++k) {
            column[k] = _mm512_setzero_ps(), target[k] = 0;
            if (k >= count || !draws[k].rows) continue;
            const ColumnDraw& c = draws[k];
            const char* row0 = static_cast<const char*>(c.rows);
            column[k] = _mm512_fmadd_ps(
                _mm512_set1_ps(c.t0), row(row0),
                _mm512_mul_ps(_mm512_set1_ps(c.t1), row(row0 + sizeof(uint16_t) * size_t(n))));
            target[k] = c.target;
        }
        invert_linear_lanes(column, n, target, out);
        return;
    }
#endif
    for (int k = 0; k < count; ++k) {
        const ColumnDraw& c = draws[k];
        if (!c.rows) continue;
        const char* row0 = static_cast<const char*>(c.rows);
        const char* row1 = row0 + sizeof(uint16_t) * size_t(n);
        float column[MlvqGrid::kMaxAxis];
        for (int j = 0; j < n; ++j)
            column[j] = c.t0 * DecodedBooks::luminance_at(row0, j) +
                        c.t1 * DecodedBooks::luminance_at(row1, j);
        out[k] = invert_linear_loop([&column](int j) { return double(column[j]); }, n, c.target);
    }
}

// Uniform hemisphere: (ξ1, ξ2) → direction, pdf 1 / 2π.
Vec3 uniform_hemisphere(double xi1, double xi2) {
    const double z = xi1, r = std::sqrt(std::max(0.0, 1 - z * z)), phi = 2 * kPi * xi2;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

}  // namespace

// One sample() in stages, so that sample_batch() can run a group of queries through each stage
// and prefetch what the next stage reads; sample() runs the stages one after the other.
struct MlvqMaterial::SampleState {
    Uv uv;
    Vec3 wo;
    double xi1 = 0, xi2 = 0;
    TexelCorners corners;
    Mixture mix;
    int component = 0;    ///< the mixture component drawn
    int i0 = 0;           ///< its α row below the drawn α
    double x = 0, y = 0;  ///< drawn (α, u) as fractional sample indices
    LightSample out;
    /// A stochastic shading point's sampling (sample_selected()): the mixture is its one term.
    bool stochastic = false;
    Selection selection;
};

// View lookup and texels.
void MlvqMaterial::sample_begin(const SampleQuery& q, SampleState& s) const {
    s.uv = q.uv;
    s.wo = q.wo;
    s.xi1 = filter_number(q.xi1);
    s.xi2 = filter_number(q.xi2);
    s.mix.view = lookup_view(m_books->grid, q.wo);
    s.corners = texel_corners(q.uv, m_index.width, m_index.height);
}

// The masses of the mixture's components (gathered into s.mix.g).
void MlvqMaterial::sample_mixture(SampleState& s) const {
    s.mix.total = 0;
    const int n_alpha = m_books->grid.n_alpha;
    for (int c = 0; c < s.mix.g.count; ++c) {
        const double mass = double(s.mix.g.y_scale[c]) * m_decoded->rows(s.mix.g.index[c])[n_alpha];
        s.mix.mass[c] = mass > 0 ? mass : 0;
        s.mix.total += s.mix.mass[c];
    }
    // Scales of a crafted package can multiply beyond the float range: no masses to sample by.
    if (!std::isfinite(s.mix.total)) s.mix.total = 0;
}

// The component, then α by the inverse CDF of its row masses (ξ1 rescaled within its share),
// for states[0 … count − 1] (count ≤ kDraws, their inversions together).
void MlvqMaterial::sample_alpha(SampleState* states, size_t count) const {
    const int n_alpha = m_books->grid.n_alpha;
    const float* rows[kDraws] = {};
    double target[kDraws], x[kDraws];
    for (size_t k = 0; k < count; ++k) {
        SampleState& s = states[k];
        if (!(s.mix.total > 0)) continue;
        double mass = s.xi1 * s.mix.total;
        int c = 0;
        while (c + 1 < s.mix.g.count && (mass >= s.mix.mass[c] || s.mix.mass[c] == 0))
            mass -= s.mix.mass[c++];
        const double share = std::clamp(mass / s.mix.mass[c], 0.0, 1.0);
        s.component = c;
        rows[k] = m_decoded->rows(s.mix.g.index[c]);
        target[k] = share * rows[k][n_alpha];
    }
    invert_rows(rows, int(count), n_alpha, target, x);
    for (size_t k = 0; k < count; ++k) {
        if (!rows[k]) continue;
        states[k].x = x[k];
        states[k].i0 = std::min(int(x[k]), n_alpha - 2);
    }
}

// u by the inverse CDF of the conditional along the two neighbouring rows; the direction and
// the light weights of (α, u) (what lookup(wi, wo) returns up to rounding). For states[0 …
// count − 1] (count ≤ kDraws, their inversions together).
void MlvqMaterial::sample_beta(SampleState* states, size_t count) const {
    const MlvqGrid& g = m_books->grid;
    ColumnDraw draws[kDraws];
    double y[kDraws];
    for (size_t k = 0; k < count; ++k) {
        const SampleState& s = states[k];
        if (!(s.mix.total > 0)) continue;
        // The column at α blends the two rows' luminances; its trapezoid sum is linear in the
        // rows': their precomputed integrals blended.
        const double tx = s.x - s.i0;
        const uint32_t m = s.mix.g.index[s.component];
        const float* rows = m_decoded->rows(m);
        const double row_mass = (1 - tx) * rows[s.i0] + tx * rows[s.i0 + 1];
        draws[k] = {m_decoded->luminance_row(m, s.i0), float(1 - tx), float(tx), s.xi2 * row_mass};
    }
    invert_columns(g.n_beta, draws, int(count), y);
    for (size_t k = 0; k < count; ++k) {
        SampleState& s = states[k];
        if (!draws[k].rows) {
            s.out.wi = uniform_hemisphere(s.xi1, s.xi2);
            continue;
        }
        s.y = y[k];
        const double tx = s.x - s.i0;
        const double alpha = -kPi / 2 + kPi * s.x / (g.n_alpha - 1);
        const double u = -1 + 2 * s.y / (g.n_beta - 1);
        s.out.wi = direction_from_onion_u(alpha, u, s.mix.view.frame);
        s.out.wi.z = std::max(s.out.wi.z, 0.0);
        MlvqWeights w = s.mix.view.weights;
        const int j0 = std::min(int(s.y), g.n_beta - 2);
        w.alpha = {{s.i0, s.i0 + 1}, {float(1 - tx), float(tx)}};
        w.beta = {{j0, j0 + 1}, {float(1 - (s.y - j0)), float(s.y - j0)}};
        if (!(s.y > 0 && s.y < g.n_beta - 1)) {
            // A pole of the onion frame (u = ±1, a draw at ξ2 = 0 or 1): the direction does not
            // depend on α there, and eval() and pdf() of it look α up as 0. The corners of the
            // direction itself, so that they agree.
            MlvqWeights at;
            lookup_lights(g, &s.out.wi, &s.mix.view, 1, &at);
            w.alpha = at.alpha, w.beta = at.beta;
        }
        s.mix.g.corners = DecodedBooks::Corners(g, w);
    }
}

// The model at the drawn direction: its value, and its luminance over the mixture's mass as pdf.
void MlvqMaterial::sample_finish(SampleState& s) const {
    LightSample& out = s.out;
    if (!(s.mix.total > 0)) {
        out.pdf = 1 / (2 * kPi);
        out.value = s.stochastic ? eval_selected(s.selection, s.uv, s.wo, out.wi)
                                 : eval(s.uv, out.wi, s.wo);
    } else {
        const std::array<float, 3> p = combine(s.mix.g);
        out.pdf = std::max(0.0, double(p[0])) / (s.mix.total * Mixture::cell(m_books->grid));
        out.value = from_planes(m_books->colour, p[0], p[1], p[2]);
    }
    out.weight = {};
    if (out.pdf > 0) {
        const double inverse = 1 / out.pdf;
        out.weight = {float(out.value.r * inverse), float(out.value.g * inverse),
                      float(out.value.b * inverse)};
    }
}

LightSample MlvqMaterial::sample(const Uv& uv, const Vec3& wo, double xi1, double xi2) const {
    SampleState s;
    sample_begin({uv, wo, xi1, xi2}, s);
    gather(s.corners, s.mix.view.weights, s.mix.g);
    sample_mixture(s);
    sample_alpha(&s, 1);
    sample_beta(&s, 1);
    sample_finish(s);
    return s.out;
}

void MlvqMaterial::sample_batch(std::span<const SampleQuery> queries,
                                std::span<LightSample> out) const {
    if (queries.size() != out.size())
        fail("sample_batch: {} queries but {} outputs", queries.size(), out.size());
    // The stages of sample() for a group at a time, each prefetching what the next one reads
    // (as eval_batch does): P6, P4 ∘ P3, the entries' row masses, the drawn rows, the corners.
    constexpr size_t kGroup = 16;
    std::vector<SampleState> group(kGroup);
    for (size_t begin = 0; begin < queries.size(); begin += kGroup) {
        const size_t n = std::min(kGroup, queries.size() - begin);
        for (size_t i = 0; i < n; ++i) {
            sample_begin(queries[begin + i], group[i]);
            for (int k = 0; k < 4; ++k)
                __builtin_prefetch(&m_index.p6[size_t(group[i].corners.texel[k])]);
        }
        for (size_t i = 0; i < n; ++i) prefetch_views(group[i].corners, group[i].mix.view.weights);
        for (size_t i = 0; i < n; ++i) {
            SampleState& s = group[i];
            gather(s.corners, s.mix.view.weights, s.mix.g);
            for (int c = 0; c < s.mix.g.count; ++c)
                __builtin_prefetch(m_decoded->rows(s.mix.g.index[c]));
        }
        for (size_t i = 0; i < n; ++i) sample_mixture(group[i]);
        for (size_t i = 0; i < n; i += kDraws) {
            sample_alpha(&group[i], std::min<size_t>(kDraws, n - i));
            for (size_t k = i; k < std::min<size_t>(i + kDraws, n); ++k)
                if (group[k].mix.total > 0)
                    prefetch_luminance_rows(*m_decoded, group[k].mix.g.index[group[k].component],
                                            group[k].i0);
        }
        for (size_t i = 0; i < n; i += kDraws)
            sample_beta(&group[i], std::min<size_t>(kDraws, n - i));
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < group[i].mix.g.count; ++c) group[i].mix.g.prefetch(c);
        for (size_t i = 0; i < n; ++i) {
            sample_finish(group[i]);
            out[begin + i] = group[i].out;
        }
    }
}

double MlvqMaterial::pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const {
    if (!(wi.z >= 0)) return 0;
    SampleState s;
    sample_begin({uv, wo, 0, 0}, s);
    gather(s.corners, s.mix.view.weights, s.mix.g);
    sample_mixture(s);
    if (!(s.mix.total > 0)) return 1 / (2 * kPi);
    const MlvqGrid& g = m_books->grid;
    s.mix.g.corners = DecodedBooks::Corners(g, lookup(g, wi, wo));
    return std::max(0.0, double(combine(s.mix.g)[0])) / (s.mix.total * Mixture::cell(g));
}

Rgb MlvqMaterial::albedo(const Uv& uv, const Vec3& wo) const {
    const Codebooks& b = *m_books;
    const MlvqGrid& g = b.grid;
    const MlvqWeights view = lookup(g, to_mlvq(Vec3{0, 0, 1}, wo));
    // Per grid sample (α_i, β_j): the planes blended over the 4 texels × 2 φv × 2 θv corners, as
    // eval() blends them at that sample. Each sample is read from its own α slice, also at the
    // poles of β, where a direction would not say which slice it belongs to.
    const int samples = g.n_alpha * g.n_beta;
    std::vector<double> y(size_t(samples), 0.0), c1(size_t(samples), 0.0), c2(size_t(samples), 0.0);
    const TexelCorners corners = texel_corners(uv, m_index.width, m_index.height);
    const DecodedBooks& d = *m_decoded;
    // Grid sample s (α-major) → its offset in an entry.
    std::vector<int> at(static_cast<size_t>(samples));
    for (int s = 0; s < samples; ++s)
        at[size_t(s)] = DecodedBooks::offset(g, s / g.n_beta, s % g.n_beta);
    for (int k = 0; k < 4; ++k) {
        if (corners.weight[k] == 0) continue;
        const IndexScale& e6 = m_index.p6[size_t(corners.texel[k])];
        for (int p = 0; p < 2; ++p)
            for (int q = 0; q < 2; ++q) {
                const double wt =
                    double(corners.weight[k]) * view.phi_v.weight[p] * view.theta_v.weight[q];
                if (wt == 0) continue;
                const IndexScale& v = d.view(e6.index, view.phi_v.index[p], view.theta_v.index[q]);
                const DecodedBooks::Sample* f = d.entry(v.index);
                const double ys = wt * e6.scale * v.scale;
                for (int s = 0; s < samples; ++s) {
                    const DecodedBooks::Sample& sample = f[at[size_t(s)]];
                    const std::array<float, 2> c = d.chroma(sample);
                    y[size_t(s)] += ys * DecodedBooks::luminance(sample);
                    c1[size_t(s)] += wt * c[0];
                    c2[size_t(s)] += wt * c[1];
                }
            }
    }
    double r = 0, gg = 0, bb = 0;
    if (b.colour == ColourModel::kYCbCr) {
        // Linear in (Y, Cb, Cr): integrate the planes, then convert.
        double sy = 0, s1 = 0, s2 = 0;
        for (int s = 0; s < samples; ++s) {
            const double lw = g.light_weight(s / g.n_beta, s % g.n_beta);
            sy += lw * y[size_t(s)];
            s1 += lw * c1[size_t(s)];
            s2 += lw * c2[size_t(s)];
        }
        const Rgb integral = from_planes(b.colour, float(sy), float(s1), float(s2));
        r = integral.r;
        gg = integral.g;
        bb = integral.b;
    } else {
        // LogLuv: the conversion is not linear; sum the converted samples instead.
        for (int s = 0; s < samples; ++s) {
            const double lw = g.light_weight(s / g.n_beta, s % g.n_beta);
            const Rgb v = from_planes(b.colour, float(y[size_t(s)]), float(c1[size_t(s)]),
                                      float(c2[size_t(s)]));
            r += lw * v.r;
            gg += lw * v.g;
            bb += lw * v.b;
        }
    }
    return {float(r / kPi), float(gg / kPi), float(bb / kPi)};
}

// ---- stochastic filtering -----------------------------------------------------------------------

// The directions of a shading point go through lookup_views() and lookup_lights() with n = 1,
// and its draw through select_views(): the code the batches run four queries at a time, so that
// both give the same bits.
Selection MlvqMaterial::select(const Uv& uv, const Vec3& wo, double u) const {
    ViewLookup view;
    lookup_views(m_books->grid, &wo, 1, &view);
    const struct {
        Uv uv;
        double u;
    } query{uv, u};
    Selection s;
    select_views(&query, &view, 1, &s);
    return s;
}

// The selection's M entry as a one-component Gathered: luminance scale c_P6 · c_P4 · c_P3 and
// chromaticity weight 1 (the weights of eval()'s sum are what the draw's probabilities stand
// for). The corners are the caller's.
void MlvqMaterial::gather_selected(const Selection& s, Gathered& out) const {
    const IndexScale& e6 = m_index.p6[size_t(s.y) * size_t(m_index.width) + size_t(s.x)];
    const IndexScale& v = m_decoded->views(e6.index)[s.view];
    out.count = 1;
    out.index[0] = v.index;
    out.entry[0] = m_decoded->entry(v.index);
    out.y_scale[0] = e6.scale * v.scale;
    out.c_weight[0] = 1;
}

// The (α, β) corners of ωi in the onion frame of ωo.
DecodedBooks::Corners MlvqMaterial::light_corners(const Vec3& wi, const Vec3& wo) const {
    ViewLookup view;
    lookup_views(m_books->grid, &wo, 1, &view);
    MlvqWeights w;
    lookup_lights(m_books->grid, &wi, &view, 1, &w);
    return DecodedBooks::Corners(m_books->grid, w);
}

// Bilinear in (α, β) within the one entry rather than a draw of one of its 4 light samples: the
// 2 × 2 samples are two adjacent 8-byte reads, and a deterministic term keeps the variance to
// that of the texel and the view node.
Rgb MlvqMaterial::eval_selected(const Selection& s, const Uv&, const Vec3& wo,
                                const Vec3& wi) const {
    Gathered g;
    gather_selected(s, g);
    g.corners = light_corners(wi, wo);
    const std::array<float, 3> p = combine(g);
    return from_planes(m_books->colour, p[0], p[1], p[2]);
}

// sample()'s stages with the selection's entry as the whole mixture (gather_selected() next).
void MlvqMaterial::sample_selected_begin(const Selection& s, const Uv& uv, const Vec3& wo,
                                         const ViewLookup& view, double xi1, double xi2,
                                         SampleState& out) const {
    out.uv = uv;
    out.wo = wo;
    out.xi1 = filter_number(xi1);
    out.xi2 = filter_number(xi2);
    out.mix.view = view;
    out.stochastic = true;
    out.selection = s;
}

LightSample MlvqMaterial::sample_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                                          double xi1, double xi2) const {
    SampleState st;
    ViewLookup view;
    lookup_views(m_books->grid, &wo, 1, &view);
    sample_selected_begin(s, uv, wo, view, xi1, xi2, st);
    gather_selected(s, st.mix.g);
    sample_mixture(st);
    sample_alpha(&st, 1);
    sample_beta(&st, 1);
    sample_finish(st);
    return st.out;
}

double MlvqMaterial::pdf_selected(const Selection& s, const Uv&, const Vec3& wo,
                                  const Vec3& wi) const {
    if (!(wi.z >= 0)) return 0;
    SampleState st;
    gather_selected(s, st.mix.g);
    sample_mixture(st);
    if (!(st.mix.total > 0)) return 1 / (2 * kPi);
    st.mix.g.corners = light_corners(wi, wo);
    return std::max(0.0, double(combine(st.mix.g)[0])) /
           (st.mix.total * Mixture::cell(m_books->grid));
}

// One term of eval()'s sum per query, drawn with probability equal to its weight there: a view
// node of the 2 φv × 2 θv by φv weight × θv weight, then a texel of the 4 by its bilinear weight
// (x, then y), in Material::select()'s order, each with pick_lanes() and what the previous draw
// left of u; four queries in the lanes.
template <typename Query>
void MlvqMaterial::select_views(const Query* queries, const ViewLookup* view, size_t count,
                                Selection* out) const {
    static_assert(kPickLanes == 4);
    WrapLerp lx[4], ly[4];
    const MlvqWeights* w[4];
    for (size_t i = 0; i < 4; ++i) {
        const size_t k = i < count ? i : 0;  // lanes past the count repeat the first query
        lx[i] = wrap_lerp(queries[k].uv.u, m_index.width);
        ly[i] = wrap_lerp(queries[k].uv.v, m_index.height);
        w[i] = &view[k].weights;
    }
    // Vectors built whole from their lanes' values (not lane by lane through memory).
    auto lanes = [](auto value) { return PickLanes{value(0), value(1), value(2), value(3)}; };
    PickLanes u = lanes([&](int i) { return filter_number(queries[i < int(count) ? i : 0].u); });
    // The float products gather() weights the nodes with, in its order (φv major); 1 − t rounded
    // to float.
    PickLanes wv[4];
    for (int node = 0; node < 4; ++node)
        wv[node] = lanes([&](int i) {
            const float product = w[i]->phi_v.weight[node >> 1] * w[i]->theta_v.weight[node & 1];
            return double(product);
        });
    const PickLanes wx[2] = {lanes([&](int i) { return double(1 - lx[i].t); }),
                             lanes([&](int i) { return double(lx[i].t); })};
    const PickLanes wy[2] = {lanes([&](int i) { return double(1 - ly[i].t); }),
                             lanes([&](int i) { return double(ly[i].t); })};
    const PickMask last4[4] = {PickMask{}, PickMask{}, PickMask{}, ~PickMask{}};
    const PickMask last2[2] = {PickMask{}, ~PickMask{}};
    const PickMask node = pick_lanes<4>(wv, last4, u);
    const PickMask px = pick_lanes<2>(wx, last2, u);
    const PickMask py = pick_lanes<2>(wy, last2, u);
    const int n_theta_v = m_decoded->grid().n_theta_v;
    for (size_t i = 0; i < count; ++i) {
        Selection& s = out[i];
        s.u = u[i];
        s.view = w[i]->phi_v.index[node[i] >> 1] * n_theta_v + w[i]->theta_v.index[node[i] & 1];
        s.x = px[i] == 0 ? lx[i].i0 : lx[i].i1;
        s.y = py[i] == 0 ? ly[i].i0 : ly[i].i1;
    }
}

void MlvqMaterial::eval_stochastic_batch(std::span<const StochasticQuery> queries,
                                         std::span<Rgb> out) const {
    if (queries.size() != out.size())
        fail("eval_stochastic_batch: {} queries but {} outputs", queries.size(), out.size());
    constexpr size_t kStages = 4;
    struct State {
        Selection selection;
        ViewLookup view;
        Gathered g;
    };
    State ring[kStages][kBlock];
    const MlvqGrid& grid = m_books->grid;
    auto p6 = [this](const Selection& s) -> const IndexScale& {
        return m_index.p6[size_t(s.y) * size_t(m_index.width) + size_t(s.x)];
    };
    pipeline<kStages>(queries.size(), [&](size_t stage, size_t first, size_t count, size_t slot) {
        const StochasticQuery* q = queries.data() + first;
        State* s = ring[slot];
        Vec3 d[kBlock];
        switch (stage) {
            case 0: {  // the view and the draw
                ViewLookup view[kBlock];
                for (size_t i = 0; i < count; ++i) d[i] = q[i].wo;
                lookup_views(grid, d, count, view);
                Selection selection[kBlock];
                select_views(q, view, count, selection);
                for (size_t i = 0; i < count; ++i) {
                    s[i].view = view[i];
                    s[i].selection = selection[i];
                    __builtin_prefetch(&p6(s[i].selection));
                }
                break;
            }
            case 1: {  // the light's (α, β) corners
                ViewLookup view[kBlock];
                MlvqWeights w[kBlock];
                for (size_t i = 0; i < count; ++i) d[i] = q[i].wi, view[i] = s[i].view;
                lookup_lights(grid, d, view, count, w);
                for (size_t i = 0; i < count; ++i) {
                    s[i].g.corners = DecodedBooks::Corners(grid, w[i]);
                    const Selection& sel = s[i].selection;
                    __builtin_prefetch(m_decoded->views(p6(sel).index) + sel.view);
                }
                break;
            }
            case 2:  // the M entry
                for (size_t i = 0; i < count; ++i) {
                    gather_selected(s[i].selection, s[i].g);
                    s[i].g.prefetch(0);
                }
                break;
            default:
                for (size_t i = 0; i < count; ++i) {
                    const std::array<float, 3> p = combine(s[i].g);
                    out[first + i] = from_planes(m_books->colour, p[0], p[1], p[2]);
                }
        }
    });
}

void MlvqMaterial::sample_stochastic_batch(std::span<const StochasticSampleQuery> queries,
                                           std::span<LightSample> out) const {
    if (queries.size() != out.size())
        fail("sample_stochastic_batch: {} queries but {} outputs", queries.size(), out.size());
    // sample_selected()'s stages: the view and the draw; P6; the view entry; its M entry's
    // sampling record (all of it, 5 lines at the default grid: the rows that β reads are known
    // only once α is drawn, and a prefetch issued then arrives too late) and the draws of α and
    // β; the corners' tile and the value.
    constexpr size_t kStages = 5;
    static_assert(kBlock <= kDraws, "a block's draws are inverted together");
    SampleState ring[kStages][kBlock];
    const MlvqGrid& grid = m_books->grid;
    auto p6 = [this](const Selection& s) -> const IndexScale& {
        return m_index.p6[size_t(s.y) * size_t(m_index.width) + size_t(s.x)];
    };
    pipeline<kStages>(queries.size(), [&](size_t stage, size_t first, size_t count, size_t slot) {
        const StochasticSampleQuery* q = queries.data() + first;
        SampleState* s = ring[slot];
        switch (stage) {
            case 0: {
                Vec3 wo[kBlock];
                ViewLookup view[kBlock];
                for (size_t i = 0; i < count; ++i) wo[i] = q[i].wo;
                lookup_views(grid, wo, count, view);
                Selection selection[kBlock];
                select_views(q, view, count, selection);
                for (size_t i = 0; i < count; ++i) {
                    const Selection& sel = selection[i];
                    sample_selected_begin(sel, q[i].uv, q[i].wo, view[i], q[i].xi1, q[i].xi2, s[i]);
                    __builtin_prefetch(&p6(sel));
                }
                break;
            }
            case 1:
                for (size_t i = 0; i < count; ++i) {
                    const Selection& sel = s[i].selection;
                    __builtin_prefetch(m_decoded->views(p6(sel).index) + sel.view);
                }
                break;
            case 2:
                for (size_t i = 0; i < count; ++i) {
                    gather_selected(s[i].selection, s[i].mix.g);
                    const float* record = m_decoded->record(s[i].mix.g.index[0]);
                    prefetch_range(record, record + m_decoded->record_floats() - 1);
                }
                break;
            case 3:
                for (size_t i = 0; i < count; ++i) sample_mixture(s[i]);
                sample_alpha(s, count);
                sample_beta(s, count);
                for (size_t i = 0; i < count; ++i)
                    if (s[i].mix.total > 0) s[i].mix.g.prefetch(0);
                break;
            default:
                for (size_t i = 0; i < count; ++i) {
                    sample_finish(s[i]);
                    out[first + i] = s[i].out;
                }
        }
    });
}

}  // namespace mlvq

namespace {

class MlvqCodec final : public Codec {
  public:
    std::string_view name() const override { return mlvq::kName; }
    std::string_view description() const override {
        return "multi-level vector quantization of apparent BRDFs with importance sampling";
    }
    std::vector<ParamInfo> params() const override { return mlvq::schema().infos(); }
    void validate(const Params& params) const override { mlvq::schema().parse(params); }

    Package encode(const BtfSource& source, const Params& params,
                   Progress& progress) const override {
        const mlvq::Options o = mlvq::schema().parse(params);
        auto [books, index] = mlvq::encode(source, o, progress);
        return mlvq::to_package(books, {std::move(index)}, o);
    }

    // Several materials share the code-books (§5.1).
    bool encodes_several() const override { return true; }
    Package encode_several(std::span<const BtfSource* const> sources,
                           std::span<const std::string> names, const Params& params,
                           Progress& progress) const override {
        check(names.size() == sources.size(), "mlvq: {} names for {} materials", names.size(),
              sources.size());
        if (sources.size() == 1) return encode(*sources[0], params, progress);
        const mlvq::Options o = mlvq::schema().parse(params);
        auto [books, indices] = mlvq::encode_shared(sources, o, progress);
        for (size_t k = 0; k < indices.size(); ++k)
            if (!names[k].empty()) indices[k].name = names[k];
        return mlvq::to_package(books, indices, o);
    }

    // A package of several materials opens as its first, as the viewer shows it (open_all()).
    std::unique_ptr<Material> open(const Package& package) const override {
        return std::move(mlvq::open_all(package).front());
    }

    std::vector<std::unique_ptr<Material>> open_all(const Package& package) const override {
        std::vector<std::unique_ptr<Material>> out;
        for (auto& m : mlvq::open_all(package)) out.push_back(std::move(m));
        return out;
    }
};

}  // namespace

const Codec& mlvq_codec() {
    static const MlvqCodec codec;
    return codec;
}

}  // namespace btf
