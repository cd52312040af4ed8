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
// then 4 % more at 2.5 times it; the code-books are then frozen and every other texel takes its
// most similar P4 code-vector. The source is read twice, in bands of rows.
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
// Parameters (btf codecs mlvq):
//   threshold=1e-5     ε_P4: mse — largest mean squared error of a texel's F_x in plane units
//                      (Y ≈ reflectance), mssim — largest 98th percentile of 1 − SSIM
//   level-factor=0.4   mse: each luminance level below P4 takes this times the threshold above
//   chroma-threshold=1e-5  mse: ε of I2; I1 and C take level-factor and its square times it
//   measure=mse        mse or mssim (§4.4)
//   colour=auto        auto (ycbcr for LDR, logluv for HDR), ycbcr, logluv
//   n-alpha=11, n-beta=11, n-theta-v=7, n-phi-v=16    the grid (§6)
//   first=0.01, second=0.04, growth=2.5               training (§5.1.1)

#include "btf/codecs/mlvq/mlvq.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>

#include "btf/codecs/factor/model.h"
#include "btf/core/btf_lookup.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {

namespace mlvq {

namespace {

constexpr const char* kName = "mlvq";

std::vector<ParamInfo> parameters() {
    return {
        {"threshold", "1e-5",
         "largest error of a texel's F_x at P4: mse in plane units (Y ~ reflectance), or the 98th "
         "percentile of 1 - SSIM"},
        {"level-factor", "0.4", "mse: threshold ratio between successive luminance code-books"},
        {"chroma-threshold", "1e-5", "mse threshold of I2 (I1, C: times level-factor, its square)"},
        {"measure", "mse", "similarity measure: mse or mssim"},
        {"colour", "auto", "auto (ycbcr for LDR, logluv for HDR), ycbcr or logluv"},
        {"n-alpha", "11", "light slices (alpha)"},
        {"n-beta", "11", "samples along a slice (beta), poles included"},
        {"n-theta-v", "7", "view elevations 0-90 degrees"},
        {"n-phi-v", "16", "view azimuths (1: isotropic)"},
        {"first", "0.01", "training step 1: fraction of texels inserted at the threshold"},
        {"second", "0.04", "training step 2: fraction of texels inserted at growth x threshold"},
        {"growth", "2.5", "threshold factor of training step 2"},
    };
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
    Options o;
    EncoderOptions& e = o.encoder;
    e.threshold = params.get_double("threshold", e.threshold, 0, 1e6);
    e.level_factor = params.get_double("level-factor", e.level_factor, 1e-6, 1);
    e.threshold_i2 = params.get_double("chroma-threshold", e.threshold_i2, 0, 1e6);
    e.threshold_i1 = e.threshold_i2 * e.level_factor;
    e.threshold_c = e.threshold_i2 * e.level_factor * e.level_factor;
    e.measure = params.get_choice("measure", "mse", {"mse", "mssim"}) == "mse" ? Measure::mse
                                                                               : Measure::mssim;
    const std::string colour = params.get_choice("colour", "auto", {"auto", "ycbcr", "logluv"});
    o.colour_auto = colour == "auto";
    if (!o.colour_auto) e.colour = parse_colour_model(colour);
    e.grid.n_alpha = params.get_int("n-alpha", e.grid.n_alpha, 3, MlvqGrid::kMaxAxis);
    e.grid.n_beta = params.get_int("n-beta", e.grid.n_beta, 3, MlvqGrid::kMaxAxis);
    e.grid.n_theta_v = params.get_int("n-theta-v", e.grid.n_theta_v, 2, MlvqGrid::kMaxAxis);
    e.grid.n_phi_v = params.get_int("n-phi-v", e.grid.n_phi_v, 1, MlvqGrid::kMaxAxis);
    e.grid.validate();
    o.first_fraction = params.get_double("first", o.first_fraction, 0, 1);
    o.second_fraction = params.get_double("second", o.second_fraction, 0, 1);
    o.growth = params.get_double("growth", o.growth, 1, 1e6);
    params.check_all_used(kName, parameters());
    return o;
}

std::pair<Codebooks, TexelIndex> encode(const BtfSource& source, const Options& options,
                                        Progress& progress, EncodeReport* report) {
    const std::string what = factor::source_name(source);
    check(source.num_texels() > 0 && source.num_views() > 0 && source.num_lights() > 0,
          "{}: mlvq: empty BTF", what);
    EncoderOptions eo = options.encoder;
    if (options.colour_auto)
        eo.colour = source.info().hdr ? ColourModel::kLogLuv : ColourModel::kYCbCr;
    Encoder encoder(eo);
    const Resampler resampler(eo.grid, source.sampling());
    const int64_t n4 = eo.grid.samples(), length = 3 * n4;
    const int width = source.width(), height = source.height();
    const int64_t texels = source.num_texels();
    EncodeReport stats;
    stats.texels = texels;

    // Training texels: Halton order, step 1 first.
    const int64_t first = std::max<int64_t>(1, std::llround(options.first_fraction * texels));
    const int64_t second = std::llround(options.second_fraction * texels);
    const std::vector<int64_t> trained = halton_texels(width, height, first + second);
    std::vector<int64_t> slot(static_cast<size_t>(texels), -1);
    for (size_t i = 0; i < trained.size(); ++i) slot[size_t(trained[i])] = int64_t(i);
    std::vector<float> training(trained.size() * size_t(length));
    const int rows = band_rows(source, length, options.memory_bytes);

    double t0 = now();
    progress.begin(
        "mlvq: reading training texels",
        uint64_t(source.num_views()) * source.num_lights() * ((height + rows - 1) / rows));
    for (int y0 = 0; y0 < height; y0 += rows) {
        const int n = std::min(rows, height - y0);
        const SourceTexels raw = read_rows(source, y0, n, progress);
        parallel_for(0, int64_t(n) * width, [&](int64_t local) {
            const int64_t s = slot[size_t(int64_t(y0) * width + local)];
            if (s < 0) return;
            float* f = training.data() + size_t(s) * length;
            resampler.resample(raw, local, 1, f);
            to_planes_in_place(eo.colour, f, n4);
        });
    }
    progress.finish();
    stats.seconds_reading = now() - t0;

    t0 = now();
    std::vector<IndexScale> p6(static_cast<size_t>(texels));
    progress.begin("mlvq: training code-books", uint64_t(trained.size()));
    for (size_t i = 0; i < trained.size(); ++i) {
        if (int64_t(i) == first) encoder.scale_thresholds(options.growth);
        p6[size_t(trained[i])] =
            encoder.insert(std::span<const float>(training.data() + i * length, size_t(length)));
        progress.advance();
    }
    progress.finish();
    training = {};
    encoder.freeze();
    stats.trained = int64_t(trained.size());
    stats.seconds_training = now() - t0;

    t0 = now();
    progress.begin("mlvq: encoding texels", uint64_t(source.num_views()) * source.num_lights() *
                                                ((height + rows - 1) / rows));
    std::vector<float> band;
    for (int y0 = 0; y0 < height; y0 += rows) {
        const int n = std::min(rows, height - y0);
        const SourceTexels raw = read_rows(source, y0, n, progress);
        band.resize(size_t(n) * width * size_t(length));
        resampler.resample(raw, band);
        parallel_for(0, int64_t(n) * width, [&](int64_t t) {
            to_planes_in_place(eo.colour, band.data() + size_t(t) * length, n4);
        });
        const std::vector<IndexScale> found = encoder.nearest(band);
        for (int64_t t = 0; t < int64_t(n) * width; ++t)
            if (slot[size_t(int64_t(y0) * width + t)] < 0)
                p6[size_t(int64_t(y0) * width + t)] = found[size_t(t)];
    }
    progress.finish();
    stats.seconds_frozen = now() - t0;
    if (report) *report = stats;

    TexelIndex index;
    index.name = source.info().path.empty() ? std::string(source.info().format)
                                            : source.info().path.filename().string();
    index.width = width;
    index.height = height;
    index.sampling = source.sampling();
    index.hdr = source.info().hdr;
    index.p6 = std::move(p6);
    return {encoder.codebooks(), std::move(index)};
}

// ---- evaluation ---------------------------------------------------------------------------------

MlvqMaterial::MlvqMaterial(std::shared_ptr<const Codebooks> books, TexelIndex index)
    : m_books(std::move(books)), m_index(std::move(index)) {
    check(m_books != nullptr, "mlvq material without code-books");
    check(int64_t(m_index.p6.size()) == int64_t(m_index.width) * m_index.height,
          "mlvq material: {} P6 entries for {}×{} texels", m_index.p6.size(), m_index.width,
          m_index.height);
    for (const IndexScale& e : m_index.p6)
        check(e.index < m_books->size_p4(), "mlvq material: P6 points to P4 {} of {}", e.index,
              m_books->size_p4());
}

std::array<float, 3> MlvqMaterial::planes(int64_t texel, const MlvqWeights& w) const {
    const Codebooks& b = *m_books;
    const MlvqGrid& g = b.grid;
    const IndexScale& e6 = m_index.p6[size_t(texel)];
    float y = 0, c1 = 0, c2 = 0;
    for (int p = 0; p < 2; ++p) {
        const float wp = w.phi_v.weight[p];
        if (wp == 0) continue;
        const IndexScale& e4 = b.p4[size_t(e6.index) * g.n_phi_v + w.phi_v.index[p]];
        for (int t = 0; t < 2; ++t) {
            const float wt = wp * w.theta_v.weight[t];
            if (wt == 0) continue;
            const IndexScale& e3 = b.p3[size_t(e4.index) * g.n_theta_v + w.theta_v.index[t]];
            const std::array<uint32_t, 2>& merge = b.m[e3.index];
            const float scale = e6.scale * e4.scale * e3.scale;
            for (int a = 0; a < 2; ++a) {
                const float wa = wt * w.alpha.weight[a];
                if (wa == 0) continue;
                const int i = w.alpha.index[a];
                const IndexScale& e2 = b.p2[size_t(merge[0]) * g.n_alpha + i];
                const float* slice = b.p1.data() + size_t(e2.index) * g.n_beta;
                const uint32_t* chroma =
                    b.i1.data() + size_t(b.i2[size_t(merge[1]) * g.n_alpha + i]) * g.n_beta;
                for (int q = 0; q < 2; ++q) {
                    const float wb = wa * w.beta.weight[q];
                    const int j = w.beta.index[q];
                    y += wb * scale * e2.scale * slice[j];
                    const std::array<float, 2>& c = b.c[chroma[j]];
                    c1 += wb * c[0];
                    c2 += wb * c[1];
                }
            }
        }
    }
    return {y, c1, c2};
}

Rgb MlvqMaterial::eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    const MlvqWeights w = lookup(m_books->grid, wi, wo);
    const WrapLerp lx = wrap_lerp(uv.u, m_index.width), ly = wrap_lerp(uv.v, m_index.height);
    const int64_t r0 = int64_t(ly.i0) * m_index.width, r1 = int64_t(ly.i1) * m_index.width;
    const int64_t t[4] = {r0 + lx.i0, r0 + lx.i1, r1 + lx.i0, r1 + lx.i1};
    const float s[4] = {(1 - lx.t) * (1 - ly.t), lx.t * (1 - ly.t), (1 - lx.t) * ly.t, lx.t * ly.t};
    float y = 0, c1 = 0, c2 = 0;
    for (int k = 0; k < 4; ++k) {
        if (s[k] == 0) continue;
        const std::array<float, 3> p = planes(t[k], w);
        y += s[k] * p[0];
        c1 += s[k] * p[1];
        c2 += s[k] * p[2];
    }
    return from_planes(m_books->colour, y, c1, c2);
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

}  // namespace mlvq

namespace {

class MlvqCodec final : public Codec {
  public:
    std::string_view name() const override { return mlvq::kName; }
    std::string_view description() const override {
        return "multi-level vector quantization of apparent BRDFs with importance sampling";
    }
    std::vector<ParamInfo> params() const override { return mlvq::parameters(); }

    Package encode(const BtfSource& source, const Params& params,
                   Progress& progress) const override {
        const mlvq::Options o = mlvq::parse_options(params);
        const auto [books, index] = mlvq::encode(source, o, progress);
        Package package;
        auto& h = package.header;
        h["codec"] = mlvq::kName;
        const mlvq::EncoderOptions& e = o.encoder;
        h["params"] = {{"threshold", e.threshold},
                       {"level-factor", e.level_factor},
                       {"chroma-threshold", e.threshold_i2},
                       {"measure", e.measure == mlvq::Measure::mse ? "mse" : "mssim"},
                       {"colour", o.colour_auto ? "auto" : mlvq::to_string(e.colour)},
                       {"n-alpha", e.grid.n_alpha},
                       {"n-beta", e.grid.n_beta},
                       {"n-theta-v", e.grid.n_theta_v},
                       {"n-phi-v", e.grid.n_phi_v},
                       {"first", o.first_fraction},
                       {"second", o.second_fraction},
                       {"growth", o.growth}};
        h["width"] = index.width;
        h["height"] = index.height;
        h["views"] = factor::directions_json(index.sampling.views);
        h["lights"] = factor::directions_json(index.sampling.lights);
        h["hdr"] = index.hdr;
        h["raw_bytes_8bit"] = int64_t(index.width) * index.height * index.sampling.num_images() * 3;
        mlvq::write_codebooks(books, index.hdr, h, package.sections);
        nlohmann::json material;
        material["name"] = index.name;
        mlvq::write_texel_index(index, books.size_p4(), "", material, package.sections);
        h["materials"] = nlohmann::json::array({material});
        const mlvq::StorageSizes sizes =
            mlvq::storage_sizes(books, int64_t(index.width) * index.height, index.hdr);
        h["storage_bytes"] = sizes.bytes;
        package.declared_sections = static_cast<int>(package.sections.size());
        return package;
    }

    std::unique_ptr<Material> open(const Package& package) const override {
        if (package.codec() != mlvq::kName)
            fail("package of codec '{}' opened as {}", package.codec(), mlvq::kName);
        try {
            const auto& h = package.header;
            auto books = std::make_shared<const mlvq::Codebooks>(mlvq::read_codebooks(package));
            mlvq::TexelIndex index;
            index.width = h.at("width").get<int>();
            index.height = h.at("height").get<int>();
            if (index.width < 1 || index.height < 1 || index.width > (1 << 16) ||
                index.height > (1 << 16))
                fail("bad extent {}×{}", index.width, index.height);
            index.sampling.views = factor::directions_from_json(h.at("views"));
            index.sampling.lights = factor::directions_from_json(h.at("lights"));
            index.hdr = h.value("hdr", false);
            const nlohmann::json& material = h.at("materials").at(0);
            index.name = material.at("name").get<std::string>();
            index.p6 = mlvq::read_texel_index(package, material, "", index.width, index.height,
                                              books->size_p4());
            return std::make_unique<mlvq::MlvqMaterial>(std::move(books), std::move(index));
        } catch (const nlohmann::json::exception& e) {
            fail("package (mlvq): bad header: {}", e.what());
        } catch (const Cancelled&) {
            throw;
        } catch (const Error& e) {
            if (std::string_view(e.what()).starts_with("package (mlvq)")) throw;
            fail("package (mlvq): {}", e.what());
        }
    }
};

}  // namespace

const Codec& mlvq_codec() {
    static const MlvqCodec codec;
    return codec;
}

}  // namespace btf
