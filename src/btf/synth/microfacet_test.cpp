// SPDX-License-Identifier: MIT
#include "btf/synth/microfacet.h"

#include <gtest/gtest.h>

#include <cmath>

namespace btf::synth {
namespace {

// ∫ D(h) cos θh dω over the hemisphere, midpoint rule in (cos θ, φ).
template <typename Fn>
double projected_integral(Fn&& d, int steps = 800) {
    double sum = 0;
    for (int i = 0; i < steps; ++i) {
        const double c = (i + 0.5) / steps;
        const double s = std::sqrt(1 - c * c);
        for (int j = 0; j < steps; ++j) {
            const double phi = 2 * 3.14159265358979 * (j + 0.5) / steps;
            sum += d(s * std::cos(phi), s * std::sin(phi), c) * c;
        }
    }
    return sum * 2 * 3.14159265358979 / (double(steps) * steps);
}

TEST(Microfacet, GgxIsNormalized) {
    for (const auto& alpha : {std::pair{0.3f, 0.3f}, {0.15f, 0.5f}, {0.6f, 0.9f}}) {
        const float ax = alpha.first, ay = alpha.second;
        const double integral = projected_integral(
            [&](double x, double y, double z) {
                return ggx_d(float(x), float(y), float(z), ax, ay);
            },
            2000);
        EXPECT_NEAR(integral, 1.0, 0.01) << ax << " " << ay;
    }
}

TEST(Microfacet, CharlieIsNormalized) {
    for (float r : {0.3f, 0.7f, 1.0f}) {
        const double integral =
            projected_integral([&](double, double, double z) { return charlie_d(float(z), r); });
        EXPECT_NEAR(integral, 1.0, 0.01) << r;
    }
}

TEST(Microfacet, SmithLambdaAndFresnelLimits) {
    EXPECT_FLOAT_EQ(ggx_lambda(0, 0, 1, 0.3f, 0.7f), 0.0f);
    // Anisotropy: grazing along the rough axis masks more than along the smooth one.
    const float s = std::sqrt(1 - 0.2f * 0.2f);
    EXPECT_GT(ggx_lambda(0, s, 0.2f, 0.1f, 0.5f), ggx_lambda(s, 0, 0.2f, 0.1f, 0.5f));
    EXPECT_FLOAT_EQ(ggx_lambda(s, 0, 0.2f, 0.4f, 0.1f), ggx_lambda(0, s, 0.2f, 0.1f, 0.4f));
    EXPECT_FLOAT_EQ(schlick_weight(1.0f), 0.0f);
    EXPECT_FLOAT_EQ(schlick_weight(0.0f), 1.0f);
    EXPECT_NEAR(schlick_weight(0.5f), 0.03125f, 1e-7);
}

TEST(Microfacet, DirectionalAlbedoIsAtMostOne) {
    // Smooth at normal incidence: almost every photon leaves (single scattering loses little).
    EXPECT_NEAR(ggx_directional_albedo(0, 0, 1, 0.05, 0.05, 512), 1.0, 0.03);
    for (double theta : {0.0, 0.7, 1.3}) {
        const double a = ggx_directional_albedo(std::sin(theta), 0, std::cos(theta), 0.2, 0.6);
        EXPECT_LE(a, 1.01) << theta;
        EXPECT_GT(a, 0.5) << theta;
    }
    // Rough surfaces lose energy to the missing multiple scattering.
    EXPECT_LT(ggx_directional_albedo(0.9, 0, std::sqrt(1 - 0.81), 0.9, 0.9), 0.9);
}

}  // namespace
}  // namespace btf::synth
