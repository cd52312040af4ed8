// SPDX-License-Identifier: MIT
#pragma once
/// Material: random-access evaluation of a BTF at any surface position and any pair of
/// directions, light-direction sampling and directional albedo. Implemented by every codec's
/// decoder and by the UBO2014 factorized-file reader.
///
/// Sampling and albedo follow the value convention of btfkit BTFs (see btf/synth/synth.h): a value
/// is relative to a white diffuser, value = π · f(ωi, ωo) · cos θi. The radiance reflected under
/// incident radiance L_i is therefore L_o = (1/π) ∫ L_i(ωi) · value(ωi) dωi, and the directional
/// albedo is a(x, ωo) = (1/π) ∫_Ω value(x, ωi, ωo) dωi (ρ for a Lambertian surface of albedo ρ,
/// whose value is ρ · cos θi). This is the MLVQ paper's equation 6, ∫ F cos θi dω, in its
/// convention where F excludes the cosine and the white diffuser's 1/π.
///
/// sample(), pdf() and albedo() have defaults that work for every material: the generic sampler
/// of btf/core/light_sampler.h (tabulated inverse CDFs per texel tile and sampled view, built
/// lazily and thread-safely on first use) and a quadrature over the hemisphere. A codec that can
/// sample from its own representation overrides all three together with native_sampling().
///
/// Two contracts of evaluation (filter after shading, after Pharr, Wronski, Salvi and Fajardo
/// 2024, "Filtering After Shading With Stochastic Texture Filtering"):
/// - deterministic: eval(), sample(), pdf() — the filtered value, for pictures and metrics;
/// - stochastic: a ShadingPoint made with Filter::kStochastic draws one texel with probability
///   equal to its bilinear weight and one view with probability equal to its barycentric weight
///   from one uniform number (the view first, then the texel), and every eval(ωi) then draws one
///   light the same way from what is left of that number. Its value is one term of the filter's
///   sum, so its mean over the number is exactly eval()'s value wherever the codec's decoding
///   after interpolation is linear (rgb, decorrelated and per-channel planes, YCbCr; the RGB
///   materials of files): see docs/codecs.md for the codecs whose colour decoding is not. A
///   shading point keeps its selection, so eval, sample and pdf at one path vertex agree (MIS
///   sees one member of a mixture whose mean is the filtered BTF). The selection lives here,
///   once (Material::select()); a codec supplies the uninterpolated lookup (eval_sample()) and
///   may override the selected lookups for speed or for its own interpolation (mlvq).

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <optional>
#include <span>
#include <string>

#include "btf/core/direction.h"
#include "btf/core/math.h"

namespace btf {

/// Texture coordinates: u across image columns, v across rows, both in [0, 1) and wrapping;
/// (0, 0) is the corner of texel (0, 0), the first pixel of the first image row.
struct Uv {
    double u = 0, v = 0;
};

/// One query of a batched evaluation.
struct Query {
    Uv uv;
    Vec3 wi, wo;  ///< light and view direction
};

/// One uninterpolated sample of a batched eval_sample(): an integer texel and sample indices.
struct SampleIndex {
    int x = 0, y = 0, view = 0, light = 0;
};

/// One light direction drawn by Material::sample().
struct LightSample {
    Vec3 wi;         ///< the light direction: a unit vector with z ≥ 0
    double pdf = 0;  ///< its probability density per unit solid angle over the upper hemisphere
    Rgb value;       ///< the BTF value eval(uv, wi, wo)
    /// value / pdf (zero when pdf is 0): a one-sample estimate of ∫_Ω value dωi = π · albedo.
    /// Under incident radiance L_i, L_i(wi) · weight / π estimates the reflected radiance.
    Rgb weight;
};

/// One request of Material::sample_batch(): position, view direction and the two random numbers.
struct SampleQuery {
    Uv uv;
    Vec3 wo;
    double xi1 = 0, xi2 = 0;
};

/// Which of the two evaluation contracts a renderer asks for (see above).
enum class Filter {
    kDeterministic,  ///< eval(): bilinear × barycentric × barycentric, every term
    kStochastic,     ///< one term, drawn with probability equal to its weight
};
/// "deterministic" or "stochastic".
const char* to_string(Filter filter);
/// Parses "deterministic" or "stochastic"; throws btf::Error naming `what` otherwise.
Filter parse_filter(const std::string& text, const std::string& what = "filter");

/// One term of the filter at a shading point: a texel, a view, and the uniform number left for
/// drawing a light. `view` indexes sampling().views for every material that uses the shared
/// angular interpolation, and a codec's own view node for one that overrides select() (mlvq).
struct Selection {
    int x = 0, y = 0;
    int view = 0;
    double u = 0;  ///< in [0, 1): what is left of the shading point's number
};

/// One query of a stochastic batch: eval() through a stochastic ShadingPoint with number u.
struct StochasticQuery {
    Uv uv;
    Vec3 wi, wo;
    double u = 0;
};

/// One query of a stochastic sampling batch: sample() of a stochastic ShadingPoint.
struct StochasticSampleQuery {
    Uv uv;
    Vec3 wo;
    double u = 0;  ///< the shading point's number
    double xi1 = 0, xi2 = 0;
};

/// Draws index i of `count` ≤ N weights with probability weight[i] / Σ weight from u ∈ [0, 1),
/// and replaces u by its position inside the drawn interval (uniform in [0, 1) again and
/// independent of i), so one number serves several draws. Zero weights are never drawn; all zero
/// draws 0. Weights must not be negative (bilinear and barycentric weights are not): a zero
/// weight then adds exactly nothing to the running sums, which need no skipping.
///
/// Without branches: which interval a random number falls in is a coin toss, and a mispredicted
/// branch discards the work the processor had started on the next queries (the 4 dependent
/// picks of a stochastic query: 55 ns with branches, 45 ns without, measured on random weights).
template <int N, typename W>
inline int pick(const W* weight, int count, double& u) {
    static_assert(N >= 1 && N <= 32);
    double value[N], low[N];
    double total = 0;
    for (int i = 0; i < N; ++i) {
        value[i] = i < count ? double(weight[i]) : 0.0;
        low[i] = total;
        total += value[i];
    }
    if (!(total > 0)) return 0;
    const double target = u * total;
    // Bit i: the draw stops at i (a positive weight whose interval holds target, or the last).
    unsigned stops = 0, positive = 0;
    for (int i = 0; i < N; ++i) {
        const unsigned p = value[i] > 0;
        positive |= p << i;
        stops |= (p & ((target < low[i] + value[i]) | (i + 1 == count))) << i;
    }
    if (stops == 0) {  // rounding left target beyond the last positive weight's interval
        u = 0x1.fffffffffffffp-1;
        return 31 - __builtin_clz(positive);
    }
    const int i = __builtin_ctz(stops);
    u = std::min(std::max((target - low[i]) / value[i], 0.0), 0x1.fffffffffffffp-1);
    return i;
}

class Material;
class LightSampler;
class AngularInterpolator;

namespace detail {
/// The generic light sampler of a Material, built on first use (double-checked under a mutex;
/// lookups after that are one acquire load). A copy of a material starts without one: the
/// sampler refers to the material it was built for.
class LazyLightSampler {
  public:
    LazyLightSampler() = default;
    LazyLightSampler(const LazyLightSampler&) {}
    LazyLightSampler& operator=(const LazyLightSampler&);
    ~LazyLightSampler();
    const LightSampler& get(const Material& material) const;

  private:
    mutable std::atomic<const LightSampler*> m_sampler{nullptr};
    mutable std::mutex m_mutex;
};

/// The angular interpolators over a material's views and lights, for the default stochastic
/// selection; built on first use like LazyLightSampler.
struct Interpolators;
class LazyInterpolators {
  public:
    LazyInterpolators() = default;
    LazyInterpolators(const LazyInterpolators&) {}
    LazyInterpolators& operator=(const LazyInterpolators&);
    ~LazyInterpolators();
    const Interpolators& get(const Material& material) const;

  private:
    mutable std::atomic<const Interpolators*> m_value{nullptr};
    mutable std::mutex m_mutex;
};
}  // namespace detail

class ShadingPoint;

class Material {
  public:
    virtual ~Material() = default;

    /// Spatial resolution of the material's textures.
    virtual int width() const = 0;
    virtual int height() const = 0;
    /// The directions the material was sampled at.
    virtual const Sampling& sampling() const = 0;

    /// BTF value (linear RGB) at texture position `uv` for light direction `wi` and view
    /// direction `wo` (unit vectors in the local frame, z = normal), interpolated smoothly:
    /// bilinear in space × barycentric over the ≤3 nearest views × ≤3 nearest lights.
    virtual Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const = 0;

    /// Value at exact sample indices and an integer texel (no interpolation).
    virtual Rgb eval_sample(int x, int y, int view, int light) const = 0;

    /// eval_sample() for every index, the same values; out.size() must equal indices.size().
    /// Implementations may prefetch what later indices read, so that random samples arrive at
    /// the memory system's rate rather than one miss after another.
    virtual void eval_sample_batch(std::span<const SampleIndex> indices, std::span<Rgb> out) const;

    /// eval() for every query; out.size() must equal queries.size(). Implementations may
    /// reuse work between consecutive queries with the same directions.
    virtual void eval_batch(std::span<const Query> queries, std::span<Rgb> out) const {
        for (size_t i = 0; i < queries.size(); ++i)
            out[i] = eval(queries[i].uv, queries[i].wi, queries[i].wo);
    }

    /// Draws a light direction for position `uv` and view direction `wo` from (xi1, xi2) ∈
    /// [0,1)² (values outside are clamped), with a density roughly proportional to the value's
    /// luminance; continuous in (xi1, xi2) wherever the method allows. Deterministic and
    /// thread-safe. Default: generic_sampler().sample().
    virtual LightSample sample(const Uv& uv, const Vec3& wo, double xi1, double xi2) const;
    /// sample() for every query; out.size() must equal queries.size(). The same results as
    /// sample() one by one; implementations may overlap the memory accesses of many queries.
    virtual void sample_batch(std::span<const SampleQuery> queries,
                              std::span<LightSample> out) const;
    /// The density (per unit solid angle) with which sample(uv, wo, ·, ·) draws `wi`: the pdf
    /// sample() reports for that direction, exactly or, where a codec draws in its own
    /// coordinates of directions (mlvq's onion angles), to within their rounding (a relative
    /// 1e-5 at most); 0 below the horizon. Default: the generic sampler.
    virtual double pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const;
    /// Directional albedo a(uv, ωo) = (1/π) ∫_Ω value(uv, ωi, ωo) dωi per channel, at `uv` and
    /// `wo` exactly. Default: quadrature_albedo() of btf/core/light_sampler.h.
    virtual Rgb albedo(const Uv& uv, const Vec3& wo) const;
    /// True when sample(), pdf() and albedo() come from the material's own representation rather
    /// than from the generic sampler.
    virtual bool native_sampling() const { return false; }

    /// The generic tabulated sampler for this material (built on first use, thread-safe), which
    /// the defaults of sample() and pdf() call; available to materials with native sampling too,
    /// for comparison.
    const LightSampler& generic_sampler() const { return m_generic_sampler.get(*this); }

    /// The stochastic filter for many queries: out[i] = ShadingPoint(*this, uv, wo, kStochastic,
    /// u).eval(wi) of query i (out.size() must equal queries.size()). Implementations may
    /// overlap the memory accesses of many queries.
    virtual void eval_stochastic_batch(std::span<const StochasticQuery> queries,
                                       std::span<Rgb> out) const;
    /// The same for sampling: out[i] = ShadingPoint(…, kStochastic, u).sample(xi1, xi2).
    virtual void sample_stochastic_batch(std::span<const StochasticSampleQuery> queries,
                                         std::span<LightSample> out) const;

  protected:
    /// The stochastic filter's hooks, reached through ShadingPoint only (so that a renderer
    /// cannot evaluate one selection and sample another). A material overrides them together
    /// or not at all, except eval_selected() alone for speed.
    ///
    /// The texel and the view of a shading point: the bilinear texels of uv (wrapping, texel
    /// centres at (x + 0.5) / width) and the barycentric views of wo, drawn by pick() from u.
    virtual Selection select(const Uv& uv, const Vec3& wo, double u) const;
    /// One term of the filter at the selection: a light drawn from the barycentric weights of wi
    /// with s.u, then eval_sample(). `uv` and `wo` are the shading point's.
    virtual Rgb eval_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                              const Vec3& wi) const;
    /// A light direction drawn for the selection, its pdf, its value eval_selected() and the
    /// weight (pdf and value as pdf() and sample() relate them). Default: the generic sampler's
    /// table of the selected texel's tile and the selected view (no blend over views).
    virtual LightSample sample_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                                        double xi1, double xi2) const;
    /// The density sample_selected() draws wi with.
    virtual double pdf_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                                const Vec3& wi) const;
    /// The shared angular interpolators over sampling().views and .lights (built on first use).
    const AngularInterpolator& view_interpolator() const;
    const AngularInterpolator& light_interpolator() const;

  private:
    friend class ShadingPoint;
    detail::LazyLightSampler m_generic_sampler;
    detail::LazyInterpolators m_interpolators;
};

/// A material at one path vertex: the position, the view direction and the filter, fixed once,
/// through which eval, sample and pdf are asked. With Filter::kStochastic the vertex draws its
/// texel and view once (from `u`), and every call uses that selection; with kDeterministic the
/// calls are Material::eval(), sample() and pdf() at (uv, wo). A renderer that holds only
/// shading points cannot mix the two contracts.
class ShadingPoint {
  public:
    ShadingPoint() = default;  ///< no material: every call returns zero
    /// `u` ∈ [0, 1) (clamped; ignored for kDeterministic): the vertex's filter number.
    /// `light_u` ∈ [0, 1), when given, is the number every eval(ωi) draws its light from instead
    /// of what the view and texel draws leave of u. It must be independent of u (a renderer
    /// passes a second stratified number): what the draws leave is itself a uniform number
    /// independent of them, so the mean stays eval()'s value.
    ShadingPoint(const Material& material, const Uv& uv, const Vec3& wo, Filter filter,
                 double u = 0, std::optional<double> light_u = {});

    Rgb eval(const Vec3& wi) const;
    LightSample sample(double xi1, double xi2) const;
    double pdf(const Vec3& wi) const;
    /// The directional albedo at (uv, wo): Material::albedo(), whatever the filter (for AOVs).
    Rgb albedo() const;

    const Material* material() const { return m_material; }
    const Uv& uv() const { return m_uv; }
    const Vec3& wo() const { return m_wo; }
    Filter filter() const { return m_filter; }
    /// The drawn term (kStochastic only).
    const Selection& selection() const { return m_selection; }

  private:
    const Material* m_material = nullptr;
    Uv m_uv;
    Vec3 m_wo;
    Filter m_filter = Filter::kDeterministic;
    Selection m_selection;
};

}  // namespace btf
