// SPDX-License-Identifier: MIT
#include "btf/render/surface.h"

#include <algorithm>
#include <cmath>

#include "btf/core/hemisphere.h"
#include "btf/core/light_sampler.h"

namespace btf::render {

namespace {

Rgb clamp_black(const Rgb& c) {
    return {std::max(c.r, 0.0f), std::max(c.g, 0.0f), std::max(c.b, 0.0f)};
}

LightSample finish(const Vec3& wi, double pdf, const Rgb& value) {
    LightSample s;
    s.wi = wi;
    s.pdf = pdf;
    s.value = value;
    s.weight = pdf > 0 ? value * float(1.0 / pdf) : Rgb{};
    return s;
}

}  // namespace

Vec3 cosine_direction(double xi1, double xi2) {
    // Uniform on the disk (Shirley–Chiu, low distortion), lifted onto the hemisphere (Malley).
    const DiskPoint d = square_to_disk({xi1, xi2});
    return {d.x, d.y, std::sqrt(std::max(0.0, 1 - d.x * d.x - d.y * d.y))};
}

// ---- BTF --------------------------------------------------------------------------------------

Vertex BtfSurface::vertex(const Uv& uv, const Vec3& wo, Filter filter, double u,
                          std::optional<double> light_u) const {
    return {uv, wo, ShadingPoint(*m_material, uv, wo, filter, u, light_u)};
}

Rgb BtfSurface::eval(const Vertex& v, const Vec3& wi) const {
    if (wi.z <= 0 || v.wo.z <= 0) return {};
    // Signed: compressed values can dip below zero (a truncated factorization rings), and a
    // value is one term of a pixel's estimate, which render() clamps at zero when it is done.
    // Clamping here instead would bias a stochastic vertex, whose one term can be negative where
    // the filtered value is not: E[max(x, 0)] ≥ max(E[x], 0) (+0.5 % on the fmf demo scene,
    // docs/benchmarks.md), and would make the two filters converge to different images.
    return v.btf.eval(wi);
}

LightSample BtfSurface::sample(const Vertex& v, double xi1, double xi2) const {
    if (m_mode == SamplingMode::kCosine) {
        const Vec3 wi = cosine_direction(xi1, xi2);
        return finish(wi, wi.z / kPi, eval(v, wi));
    }
    if (m_mode == SamplingMode::kGeneric) {
        // The generic sampler's blended tables at (uv, wo) draw the direction and give its
        // density; the value is the vertex's own (its selection, when stochastic).
        const LightSample s = m_material->generic_sampler().sample(v.uv, v.wo, xi1, xi2);
        return finish(s.wi, s.pdf, eval(v, s.wi));
    }
    return v.btf.sample(xi1, xi2);  // signed, as eval()
}

double BtfSurface::pdf(const Vertex& v, const Vec3& wi) const {
    if (wi.z <= 0) return 0;
    if (m_mode == SamplingMode::kCosine) return wi.z / kPi;
    if (m_mode == SamplingMode::kGeneric) return m_material->generic_sampler().pdf(v.uv, v.wo, wi);
    return v.btf.pdf(wi);
}

Rgb BtfSurface::albedo(const Vertex& v) const {
    return clamp_black(v.btf.albedo());
}

// ---- diffuse ----------------------------------------------------------------------------------

Rgb DiffuseSurface::eval(const Vertex& v, const Vec3& wi) const {
    if (wi.z <= 0 || v.wo.z <= 0) return {};
    return m_albedo * float(wi.z);
}

LightSample DiffuseSurface::sample(const Vertex& v, double xi1, double xi2) const {
    const Vec3 wi = cosine_direction(xi1, xi2);
    return finish(wi, wi.z / kPi, eval(v, wi));
}

double DiffuseSurface::pdf(const Vertex&, const Vec3& wi) const {
    return wi.z > 0 ? wi.z / kPi : 0;
}

Rgb DiffuseSurface::albedo(const Vertex&) const {
    return m_albedo;
}

// ---- rough conductor --------------------------------------------------------------------------

ConductorSurface::ConductorSurface(const Rgb& f0, double roughness)
    : m_f0(f0), m_alpha(std::max(roughness, 0.02)) {}

namespace {

double ggx_d(double alpha, double cos_h) {
    const double a2 = alpha * alpha, c2 = cos_h * cos_h;
    const double t = c2 * (a2 - 1) + 1;
    return a2 / (kPi * t * t);
}

double ggx_lambda(double alpha, double cos_t) {
    const double c2 = cos_t * cos_t;
    const double tan2 = std::max(0.0, 1 - c2) / c2;
    return 0.5 * (std::sqrt(1 + alpha * alpha * tan2) - 1);
}

}  // namespace

Rgb ConductorSurface::eval(const Vertex& v, const Vec3& wi) const {
    const Vec3& wo = v.wo;
    if (wi.z <= 0 || wo.z <= 0) return {};
    const Vec3 h = normalize(wi + wo);
    const double d = ggx_d(m_alpha, h.z);
    const double g = 1 / (1 + ggx_lambda(m_alpha, wi.z) + ggx_lambda(m_alpha, wo.z));
    const double s = std::pow(1 - std::clamp(dot(wi, h), 0.0, 1.0), 5);
    const Rgb f = {float(m_f0.r + (1 - m_f0.r) * s), float(m_f0.g + (1 - m_f0.g) * s),
                   float(m_f0.b + (1 - m_f0.b) * s)};
    // value = π · D G F / (4 cos θi cos θo) · cos θi
    return f * float(kPi * d * g / (4 * wo.z));
}

LightSample ConductorSurface::sample(const Vertex& v, double xi1, double xi2) const {
    const Vec3& wo = v.wo;
    // Half vectors with density D(h) cos θh, reflected about h.
    const double xi = std::min(xi1, 1 - 1e-12);
    const double tan2 = m_alpha * m_alpha * xi / (1 - xi);
    const double cos_h = 1 / std::sqrt(1 + tan2),
                 sin_h = std::sqrt(std::max(0.0, 1 - cos_h * cos_h));
    const double phi = 2 * kPi * xi2;
    const Vec3 h = {sin_h * std::cos(phi), sin_h * std::sin(phi), cos_h};
    const double wo_h = dot(wo, h);
    if (wo_h <= 0 || wo.z <= 0) return finish({0, 0, 1}, 0, {});
    const Vec3 wi = h * (2 * wo_h) - wo;
    if (wi.z <= 0) return finish(wi, 0, {});
    return finish(wi, pdf(v, wi), eval(v, wi));
}

double ConductorSurface::pdf(const Vertex& v, const Vec3& wi) const {
    const Vec3& wo = v.wo;
    if (wi.z <= 0 || wo.z <= 0) return 0;
    const Vec3 h = normalize(wi + wo);
    const double wo_h = dot(wo, h);
    if (wo_h <= 0) return 0;
    return ggx_d(m_alpha, h.z) * h.z / (4 * wo_h);
}

Rgb ConductorSurface::albedo(const Vertex& v) const {
    // (1/π) E[value / pdf] over a fixed 16 × 16 stratified grid: deterministic, and only used for
    // the albedo AOV.
    constexpr int kN = 16;
    Rgb sum;
    for (int i = 0; i < kN; ++i)
        for (int j = 0; j < kN; ++j) sum += sample(v, (i + 0.5) / kN, (j + 0.5) / kN).weight;
    return sum * float(1.0 / (kN * kN * kPi));
}

}  // namespace btf::render
