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

#include <atomic>
#include <mutex>
#include <span>

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

class Material;
class LightSampler;

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
}  // namespace detail

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
    /// The density (per unit solid angle) with which sample(uv, wo, ·, ·) draws `wi`: exactly the
    /// pdf sample() reports for that direction; 0 below the horizon. Default: the generic sampler.
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

  private:
    detail::LazyLightSampler m_generic_sampler;
};

}  // namespace btf
