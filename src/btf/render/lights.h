// SPDX-License-Identifier: MIT
#pragma once
/// The light sources of a scene, in world space (right-handed, +y up): point, directional,
/// spherical area and environment. A renderer asks a light for a direction towards it from a
/// shading point (next-event estimation) and, for lights a path can hit, for the density of that
/// direction (multiple importance sampling).

#include <limits>
#include <memory>

#include "btf/core/math.h"
#include "btf/render/environment.h"

namespace btf::render {

/// A direction towards a light from a shading point.
struct LightDirection {
    Vec3 wi;  ///< unit, from the shading point towards the light
    double distance = std::numeric_limits<double>::infinity();  ///< to the light along wi
    /// Delta lights: the irradiance on a surface facing wi (I / d² or E). Others: the radiance
    /// arriving along wi.
    Rgb radiance;
    double pdf = 0;  ///< per unit solid angle; 0 for delta lights and for failed samples
    bool delta = false;
};

class Light {
  public:
    virtual ~Light() = default;
    virtual LightDirection sample(const Vec3& p, double xi1, double xi2) const = 0;
    /// The density with which sample(p, ·) draws the direction wi (0 for delta lights).
    virtual double pdf(const Vec3& p, const Vec3& wi) const = 0;
};

/// An isotropic point light of intensity I (W/sr per channel).
class PointLight final : public Light {
  public:
    PointLight(const Vec3& position, const Rgb& intensity)
        : m_position(position), m_intensity(intensity) {}
    LightDirection sample(const Vec3& p, double, double) const override;
    double pdf(const Vec3&, const Vec3&) const override { return 0; }

  private:
    Vec3 m_position;
    Rgb m_intensity;
};

/// A distant light: irradiance E on a surface facing it, arriving from `towards` (unit, pointing
/// from the scene to the light).
class DirectionalLight final : public Light {
  public:
    DirectionalLight(const Vec3& towards, const Rgb& irradiance)
        : m_towards(normalize(towards)), m_irradiance(irradiance) {}
    LightDirection sample(const Vec3& p, double, double) const override;
    double pdf(const Vec3&, const Vec3&) const override { return 0; }

  private:
    Vec3 m_towards;
    Rgb m_irradiance;
};

/// A sphere emitting radiance L uniformly from its surface, sampled uniformly within the cone it
/// subtends (so its noise does not grow with distance). Paths can hit it.
class SphereLight final : public Light {
  public:
    SphereLight(const Vec3& centre, double radius, const Rgb& radiance)
        : m_centre(centre), m_radius(radius), m_radiance(radiance) {}
    LightDirection sample(const Vec3& p, double xi1, double xi2) const override;
    double pdf(const Vec3& p, const Vec3& wi) const override;
    /// Distance along the ray (origin o, unit direction d) to the sphere's outside, or infinity.
    double intersect(const Vec3& o, const Vec3& d) const;
    const Rgb& radiance() const { return m_radiance; }

  private:
    Vec3 m_centre;
    double m_radius;
    Rgb m_radiance;
};

/// Light from infinitely far away in every direction: an environment map, importance-sampled.
class EnvironmentLight final : public Light {
  public:
    explicit EnvironmentLight(std::shared_ptr<const EnvironmentMap> map) : m_map(std::move(map)) {}
    LightDirection sample(const Vec3& p, double xi1, double xi2) const override;
    double pdf(const Vec3&, const Vec3& wi) const override { return m_map->pdf(wi); }
    Rgb radiance(const Vec3& wi) const { return m_map->radiance(wi); }
    const EnvironmentMap& map() const { return *m_map; }

  private:
    std::shared_ptr<const EnvironmentMap> m_map;
};

/// An orthonormal basis (s, t, n) around the unit vector n (Duff et al. 2017, branchless).
void orthonormal_basis(const Vec3& n, Vec3& s, Vec3& t);

}  // namespace btf::render
