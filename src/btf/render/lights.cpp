// SPDX-License-Identifier: MIT
#include "btf/render/lights.h"

#include <algorithm>
#include <cmath>

namespace btf::render {

void orthonormal_basis(const Vec3& n, Vec3& s, Vec3& t) {
    const double sign = std::copysign(1.0, n.z);
    const double a = -1 / (sign + n.z), b = n.x * n.y * a;
    s = {1 + sign * n.x * n.x * a, sign * b, -sign * n.x};
    t = {b, sign + n.y * n.y * a, -n.y};
}

LightDirection PointLight::sample(const Vec3& p, double, double) const {
    LightDirection l;
    const Vec3 d = m_position - p;
    const double d2 = dot(d, d);
    l.distance = std::sqrt(d2);
    l.wi = d / l.distance;
    l.radiance = m_intensity * float(1 / d2);
    l.delta = true;
    return l;
}

LightDirection DirectionalLight::sample(const Vec3&, double, double) const {
    LightDirection l;
    l.wi = m_towards;
    l.radiance = m_irradiance;
    l.delta = true;
    return l;
}

LightDirection SphereLight::sample(const Vec3& p, double xi1, double xi2) const {
    LightDirection l;
    const Vec3 d = m_centre - p;
    const double dist2 = dot(d, d), r2 = m_radius * m_radius;
    if (dist2 <= r2) return l;  // inside the light: it is not sampled from there
    const double dist = std::sqrt(dist2);
    const double cos_max = std::sqrt(std::max(0.0, 1 - r2 / dist2));
    // 1 − cos θmax without cancellation: a small or distant sphere subtends a tiny cone.
    const double one_minus = (r2 / dist2) / (1 + cos_max);
    const double cos_t = 1 - xi1 * one_minus;
    const double sin_t = std::sqrt(std::max(0.0, 1 - cos_t * cos_t));
    const double phi = 2 * kPi * xi2;
    const Vec3 n = d / dist;
    Vec3 s, t;
    orthonormal_basis(n, s, t);
    l.wi = normalize(s * (sin_t * std::cos(phi)) + t * (sin_t * std::sin(phi)) + n * cos_t);
    l.distance = intersect(p, l.wi);
    if (!std::isfinite(l.distance)) {
        // Grazing the silhouette in floating point: the tangent point's distance.
        l.distance = dist * cos_t;
    }
    l.radiance = m_radiance;
    l.pdf = 1 / (2 * kPi * one_minus);
    return l;
}

double SphereLight::pdf(const Vec3& p, const Vec3& wi) const {
    const Vec3 d = m_centre - p;
    const double dist2 = dot(d, d), r2 = m_radius * m_radius;
    if (dist2 <= r2) return 0;
    const double cos_max = std::sqrt(std::max(0.0, 1 - r2 / dist2));
    if (dot(wi, d) < cos_max * std::sqrt(dist2)) return 0;
    return 1 / (2 * kPi * ((r2 / dist2) / (1 + cos_max)));
}

double SphereLight::intersect(const Vec3& o, const Vec3& d) const {
    const Vec3 oc = o - m_centre;
    const double b = dot(oc, d), c = dot(oc, oc) - m_radius * m_radius;
    const double disc = b * b - c;
    if (disc < 0) return std::numeric_limits<double>::infinity();
    const double root = std::sqrt(disc);
    const double t0 = -b - root;
    if (t0 > 0) return t0;
    return std::numeric_limits<double>::infinity();  // inside or behind: not seen from outside
}

LightDirection EnvironmentLight::sample(const Vec3&, double xi1, double xi2) const {
    const EnvSample s = m_map->sample(xi1, xi2);
    LightDirection l;
    l.wi = s.direction;
    l.radiance = s.radiance;
    l.pdf = s.pdf;
    return l;
}

}  // namespace btf::render
