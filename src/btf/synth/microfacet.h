// SPDX-License-Identifier: MIT
#pragma once
/// The microfacet pieces the synthetic materials shade with, in single precision for speed.
/// Vectors are in a local shading frame: z = the (meso-scale) surface normal, x = the tangent
/// along which roughness alpha_x applies.
///
/// - GGX / Trowbridge–Reitz distribution, anisotropic (Walter et al. 2007; Heitz 2014);
/// - Smith masking via its Λ function, combined height-correlated: G2 = 1 / (1 + Λ(wi) + Λ(wo));
/// - Schlick's Fresnel approximation;
/// - the "Charlie" sheen distribution (Estevez & Kulla 2017) with Neubelt & Pettineo's
///   visibility term, for the fuzz of fibres.

#include <cmath>

namespace btf::synth {

constexpr float kPiF = 3.14159265358979f;

/// GGX normal distribution D(h) for a unit half vector h (local frame), roughness ax, ay.
inline float ggx_d(float hx, float hy, float hz, float ax, float ay) {
    const float a = hx / ax, b = hy / ay;
    const float t = a * a + b * b + hz * hz;
    return 1.0f / (kPiF * ax * ay * t * t);
}

/// Smith Λ of GGX for a unit direction w (local frame, w.z > 0).
inline float ggx_lambda(float wx, float wy, float wz, float ax, float ay) {
    const float tan2 = (ax * ax * wx * wx + ay * ay * wy * wy) / (wz * wz);
    return 0.5f * (std::sqrt(1.0f + tan2) - 1.0f);
}

/// (1 − cos)^5, the Schlick Fresnel weight: F = F0 + (1 − F0)·weight.
inline float schlick_weight(float cos_theta) {
    const float m = std::fmax(0.0f, 1.0f - cos_theta);
    const float m2 = m * m;
    return m2 * m2 * m;
}

/// Charlie sheen distribution for the cosine of the half vector, roughness r in (0, 1].
inline float charlie_d(float cos_h, float r) {
    const float sin2 = std::fmax(0.0f, 1.0f - cos_h * cos_h);
    const float inv_r = 1.0f / r;
    return (2.0f + inv_r) * std::pow(sin2, 0.5f * inv_r) / (2.0f * kPiF);
}

/// Neubelt & Pettineo's visibility term for sheen, 1 / (4 (cos_i + cos_o − cos_i·cos_o)).
inline float sheen_visibility(float cos_i, float cos_o) {
    return 1.0f / (4.0f * (cos_i + cos_o - cos_i * cos_o));
}

/// Directional albedo of the specular GGX lobe (F = 1) for view direction wo, estimated by
/// numerical integration over the hemisphere of light directions with `steps`² samples;
/// used to check energy plausibility (≤ 1 for any parameters).
double ggx_directional_albedo(double wox, double woy, double woz, double ax, double ay,
                              int steps = 256);

}  // namespace btf::synth
