// SPDX-License-Identifier: MIT
// Decoding a UBO2014 factorization at its sample directions, and the BtfSource over it.

#include "btf/io/ubo2014.h"

#include <algorithm>
#include <cmath>

#include "btf/core/color.h"
#include "btf/util/error.h"

namespace btf::ubo2014 {

namespace fs = std::filesystem;

int Factorization::num_channels() const {
    if (meta.version >= 4 && !meta.channel_names.empty())
        return static_cast<int>(meta.channel_names.size());
    return 3;
}

std::string Factorization::signature() const {
    std::string s = body == Body::kDfmf ? "!DFMF08FC" : "!FMF12FCE";
    if (rotation_block) s += 'R';
    return s;
}

void Factorization::validate(const std::string& what) const {
    const int nc = num_channels();
    check(width > 0 && height > 0, "{}: width × height {}×{} must be positive", what, width,
          height);
    check(!sampling.views.empty() && !sampling.lights.empty(), "{}: empty view or light set", what);
    const int64_t images = sampling.num_images();
    const int64_t texels = int64_t(width) * height;
    check(nc == 3, "{}: {} colour channels; btfkit decodes 3", what, nc);
    if (body == Body::kDfmf) {
        check(color_model == kColorModelRgb || color_model == kColorModelLogYUV,
              "{}: unsupported DFMF colour model {} (btfkit decodes 0 = RGB and 11 = log Y, U/Y, "
              "V/Y)",
              what, color_model);
        check(int(factors.size()) == nc, "{}: DFMF needs {} factors (one per channel), has {}",
              what, nc, factors.size());
    } else {
        check(factors.size() == 1, "{}: FMF needs exactly one factor, has {}", what,
              factors.size());
    }
    const int64_t rows = body == Body::kDfmf ? images : images * nc;
    for (size_t c = 0; c < factors.size(); ++c) {
        const Factor& f = factors[c];
        const int64_t k = f.u.cols();
        check(f.u.rows() == rows,
              "{}: U of factor {} has {} rows, expected {} ({} views × {} "
              "lights{})",
              what, c, f.u.rows(), rows, sampling.num_views(), sampling.num_lights(),
              body == Body::kDfmf ? "" : " × channels");
        check(f.sxv.rows() == texels && f.sxv.cols() == k,
              "{}: SxV of factor {} is {}×{}, expected {}×{} (width·height × K)", what, c,
              f.sxv.rows(), f.sxv.cols(), texels, k);
        check(f.s.size() == k, "{}: S of factor {} has {} values, expected K = {}", what, c,
              f.s.size(), k);
        check(k <= std::min(rows, texels), "{}: factor {} has K = {} > min(rows, cols) = {}", what,
              c, k, std::min(rows, texels));
    }
}

namespace {

// Undoes the colour model (DFMF) or the dynamic-range reduction (FMF), then the cosine flag.
inline Rgb to_rgb(const Factorization& f, const std::array<float, 3>& c, float inv_cos) {
    Rgb rgb;
    if (f.body == Body::kFmf) {
        if (f.dynamic_range_reduction != 0)
            rgb = {std::exp(c[0]) - kDynamicRangeEps, std::exp(c[1]) - kDynamicRangeEps,
                   std::exp(c[2]) - kDynamicRangeEps};
        else
            rgb = {c[0], c[1], c[2]};
    } else if (f.color_model == kColorModelLogYUV) {
        rgb = ubo_model11_to_rgb(c);
    } else {
        rgb = {c[0], c[1], c[2]};
    }
    return rgb * inv_cos;
}

inline float inverse_cosine(const Factorization& f, int light) {
    if (!f.meta.cosine_flag) return 1.0f;
    const double z = f.sampling.lights.vector(light).z;
    return 1.0f / std::max(float(z), kMinLightCosine);
}

}  // namespace

Rgb Factorization::sample(int x, int y, int view, int light) const {
    const int nl = sampling.num_lights();
    if (x < 0 || y < 0 || x >= width || y >= height || view < 0 || light < 0 ||
        view >= sampling.num_views() || light >= nl)
        fail(
            "UBO2014 factorization: sample (x {}, y {}, view {}, light {}) outside {}×{} "
            "texels, {} views, {} lights",
            x, y, view, light, width, height, sampling.num_views(), nl);
    const int64_t texel = int64_t(y) * width + x;
    const int64_t row = int64_t(view) * nl + light;
    std::array<float, 3> c;
    if (body == Body::kDfmf) {
        for (int ch = 0; ch < 3; ++ch)
            c[ch] = factors[ch].u.row(row).dot(factors[ch].sxv.row(texel));
    } else {
        const Factor& f = factors[0];
        for (int ch = 0; ch < 3; ++ch) c[ch] = f.u.row(row * 3 + ch).dot(f.sxv.row(texel));
    }
    return to_rgb(*this, c, inverse_cosine(*this, light));
}

void Factorization::image(int view, int light, Image& out) const {
    const int nl = sampling.num_lights();
    if (view < 0 || light < 0 || view >= sampling.num_views() || light >= nl)
        fail("UBO2014 factorization: image (view {}, light {}) outside {} views × {} lights", view,
             light, sampling.num_views(), nl);
    const int64_t row = int64_t(view) * nl + light;
    const int64_t texels = int64_t(width) * height;
    // values(texel, channel): one matrix-vector product per channel over all texels.
    Eigen::MatrixXf values(texels, 3);
    if (body == Body::kDfmf) {
        for (int ch = 0; ch < 3; ++ch)
            values.col(ch).noalias() = factors[ch].sxv * factors[ch].u.row(row).transpose();
    } else {
        const Factor& f = factors[0];
        values.noalias() = f.sxv * f.u.middleRows(row * 3, 3).transpose();
    }
    out.reshape(width, height, 3);
    const float inv_cos = inverse_cosine(*this, light);
    float* p = out.data();
    for (int64_t t = 0; t < texels; ++t, p += 3) {
        const Rgb rgb = to_rgb(*this, {values(t, 0), values(t, 1), values(t, 2)}, inv_cos);
        p[0] = rgb.r, p[1] = rgb.g, p[2] = rgb.b;
    }
}

namespace {

std::string describe(const Factorization& f) {
    std::string ks;
    for (const Factor& factor : f.factors)
        ks += (ks.empty() ? "" : "/") + std::to_string(factor.components());
    const int ss = f.factors.empty() ? 4 : f.factors[0].scalar_size;
    const char* scalar = ss == 2 ? "half" : (ss == 4 ? "float32" : "float64");
    std::string colour;
    if (f.body == Body::kDfmf)
        colour = f.color_model == kColorModelLogYUV ? "colour model 11 (log Y, U/Y, V/Y)"
                                                    : "colour model 0 (RGB)";
    else
        colour =
            f.dynamic_range_reduction != 0 ? "RGB, dynamic range reduced (exp(x) − 1e-5)" : "RGB";
    return fmt::format(
        "{} {}, K = {}, {} factors, meta version {}{}{}", f.signature(), colour, ks, scalar,
        f.meta.version, f.meta.cosine_flag ? ", cosine flag divided out" : "",
        f.rotations.empty() ? "" : fmt::format(", {} rotations", f.rotations.size()));
}

class FactorizationSource final : public BtfSource {
  public:
    FactorizationSource(std::shared_ptr<const Factorization> f, const fs::path& path,
                        const std::vector<int>& views)
        : m_f(std::move(f)) {
        const std::string name = path.empty() ? "UBO2014 factorization" : path.string();
        m_f->validate(name);
        const int nv = m_f->sampling.num_views();
        if (views.empty()) {
            for (int v = 0; v < nv; ++v) m_views.push_back(v);
            m_sampling = m_f->sampling;
        } else {
            std::vector<bool> seen(nv, false);
            for (int v : views) {
                check(v >= 0 && v < nv, "{}: view index {} out of range (the file has {} views)",
                      name, v, nv);
                check(!seen[v], "{}: view index {} given twice", name, v);
                seen[v] = true;
            }
            m_views = views;
            m_sampling.views = m_f->sampling.views.subset(
                views, m_f->sampling.views.name() + fmt::format("-subset{}", views.size()));
            m_sampling.lights = m_f->sampling.lights;
        }
        m_info.format = m_f->body == Body::kDfmf ? "UBO2014 DFMF" : "UBO2014 FMF";
        m_info.path = path;
        m_info.hdr = true;
        m_info.note = describe(*m_f);
        if (!views.empty()) m_info.note += fmt::format("; {} of {} views", views.size(), nv);
    }

    int width() const override { return m_f->width; }
    int height() const override { return m_f->height; }
    const Sampling& sampling() const override { return m_sampling; }
    const SourceInfo& info() const override { return m_info; }

    void read_image(int view, int light, Image& out) const override {
        if (view < 0 || light < 0 || view >= m_sampling.num_views() ||
            light >= m_sampling.num_lights())
            fail("{}: image (view {}, light {}) out of range ({} views × {} lights)",
                 m_info.path.string(), view, light, m_sampling.num_views(),
                 m_sampling.num_lights());
        m_f->image(m_views[view], light, out);
        // Finite factors can still overflow the colour model's exp(): refuse the image here,
        // where the values enter, rather than let NaN reach a codec.
        const float* p = out.data();
        for (int64_t i = 0; i < out.num_pixels() * 3; ++i)
            if (!std::isfinite(p[i]))
                fail(
                    "{}: image (view {}, light {}): texel ({}, {}) decodes to a non-finite value "
                    "(the factors overflow the colour model)",
                    m_info.path.string(), view, light, (i / 3) % out.width(),
                    (i / 3) / out.width());
    }

    const Factorization& factorization() const { return *m_f; }

  private:
    std::shared_ptr<const Factorization> m_f;
    std::vector<int> m_views;
    Sampling m_sampling;
    SourceInfo m_info;
};

}  // namespace

std::unique_ptr<BtfSource> make_source(std::shared_ptr<const Factorization> factorization,
                                       const fs::path& path, const std::vector<int>& views) {
    return std::make_unique<FactorizationSource>(std::move(factorization), path, views);
}

std::unique_ptr<BtfSource> open(const fs::path& path, const OpenOptions& options) {
    return make_source(read(path), path, options.views);
}

}  // namespace btf::ubo2014
