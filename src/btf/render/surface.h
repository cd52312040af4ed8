// SPDX-License-Identifier: MIT
#pragma once
/// What a renderer's surface hit reflects: a BTF material (any codec's Material, with its own
/// importance sampling) or one of two simple analytic fallbacks for objects that have no measured
/// material (diffuse, rough conductor).
///
/// All directions are in the local shading frame (z = shading normal, x = tangent along +u) and
/// every value follows the BTF convention of btf/core/material.h: value = π · f_r · cos θi, so a
/// Lambertian surface of albedo ρ has value ρ · cos θi and the reflected radiance under incident
/// radiance L_i is ∫ L_i · value / π dωi.

#include <memory>
#include <optional>

#include "btf/core/material.h"
#include "btf/core/math.h"

namespace btf::render {

/// How a surface picks light directions when the path tracer extends a path.
enum class SamplingMode {
    kMaterial,  ///< the material's own sample() (BTF importance sampling)
    kCosine,    ///< cosine-weighted hemisphere sampling (the baseline BTF sampling is measured
                ///< against)
    /// the generic tabulated sampler (btf/core/light_sampler.h) even for a material with native
    /// sampling, to measure what native sampling gains
    kGeneric,
};

/// One path vertex on a surface: where and from where it is seen, and for a BTF the shading
/// point (with its filter and, when stochastic, its drawn texel and view) through which every
/// eval, sample and pdf at the vertex goes. Made once per vertex by Surface::vertex().
struct Vertex {
    Uv uv;
    Vec3 wo;
    ShadingPoint btf;  ///< the material's shading point (BtfSurface only)
};

class Surface {
  public:
    virtual ~Surface() = default;
    /// The vertex at `uv` seen from `wo` (local frame). `filter`, `u` ∈ [0, 1) (the vertex's
    /// filter number) and `light_u` (ShadingPoint's) matter to a BTF only: with
    /// Filter::kStochastic its texel and view are drawn here, once.
    virtual Vertex vertex(const Uv& uv, const Vec3& wo, Filter filter, double u,
                          std::optional<double> light_u = {}) const {
        (void)filter, (void)u, (void)light_u;
        return {uv, wo, {}};
    }
    /// True when vertex() draws with `u` under Filter::kStochastic (a BTF): the integrator takes
    /// a number from the path's generator only then, so that other surfaces' paths, and
    /// deterministic renders, keep their random sequences.
    virtual bool draws_filter_number() const { return false; }
    /// value(uv, wi, wo) at the vertex; black when either direction is below the horizon.
    virtual Rgb eval(const Vertex& v, const Vec3& wi) const = 0;
    /// A light direction for the vertex from (xi1, xi2) with its pdf per solid angle, value and
    /// value / pdf.
    virtual LightSample sample(const Vertex& v, double xi1, double xi2) const = 0;
    /// The density sample() draws `wi` with at the vertex.
    virtual double pdf(const Vertex& v, const Vec3& wi) const = 0;
    /// Directional albedo (1/π) ∫ value dωi at the vertex, for the albedo AOV (the filtered
    /// value whatever the filter).
    virtual Rgb albedo(const Vertex& v) const = 0;
};

/// A BTF material. uv wraps (the material tiles); the object's uv scale and rotation are applied
/// by the renderer before the lookup. Every call goes through the vertex's ShadingPoint, so a
/// stochastic vertex evaluates, samples and reports densities for one selection. Values are
/// signed (a compressed BTF can ring below zero; render() clamps the pixel, not the term).
class BtfSurface final : public Surface {
  public:
    BtfSurface(std::shared_ptr<const Material> material,
               SamplingMode mode = SamplingMode::kMaterial)
        : m_material(std::move(material)), m_mode(mode) {}
    Vertex vertex(const Uv& uv, const Vec3& wo, Filter filter, double u,
                  std::optional<double> light_u = {}) const override;
    bool draws_filter_number() const override { return true; }
    Rgb eval(const Vertex& v, const Vec3& wi) const override;
    LightSample sample(const Vertex& v, double xi1, double xi2) const override;
    double pdf(const Vertex& v, const Vec3& wi) const override;
    Rgb albedo(const Vertex& v) const override;
    const Material& material() const { return *m_material; }

  private:
    std::shared_ptr<const Material> m_material;
    SamplingMode m_mode;
};

/// Lambertian reflection of albedo ρ: value = ρ · cos θi, cosine-weighted sampling (exact).
class DiffuseSurface final : public Surface {
  public:
    explicit DiffuseSurface(const Rgb& albedo) : m_albedo(albedo) {}
    Rgb eval(const Vertex& v, const Vec3& wi) const override;
    LightSample sample(const Vertex& v, double xi1, double xi2) const override;
    double pdf(const Vertex& v, const Vec3& wi) const override;
    Rgb albedo(const Vertex& v) const override;

  private:
    Rgb m_albedo;
};

/// A rough metal: the GGX microfacet model with Smith's height-correlated shadowing and Schlick's
/// Fresnel from the normal-incidence reflectance F0 (per channel); sampled by the GGX normal
/// distribution. `roughness` is GGX α, clamped to ≥ 0.02 (smoother surfaces are mirrors, which
/// this renderer does not model).
class ConductorSurface final : public Surface {
  public:
    ConductorSurface(const Rgb& f0, double roughness);
    Rgb eval(const Vertex& v, const Vec3& wi) const override;
    LightSample sample(const Vertex& v, double xi1, double xi2) const override;
    double pdf(const Vertex& v, const Vec3& wi) const override;
    Rgb albedo(const Vertex& v) const override;

  private:
    Rgb m_f0;
    double m_alpha;
};

/// Cosine-weighted direction on the upper hemisphere from (xi1, xi2) (concentric disk mapping);
/// its pdf is cos θ / π.
Vec3 cosine_direction(double xi1, double xi2);

}  // namespace btf::render
