// SPDX-License-Identifier: MIT
#include "btf/synth/microfacet.h"

#include <cmath>

#include "btf/core/math.h"

namespace btf::synth {

double ggx_directional_albedo(double wox, double woy, double woz, double ax, double ay, int steps) {
    // Midpoint rule in (cos²θ, φ): dω·cosθ = ½ d(cos²θ) dφ, so the cosine-weighted
    // hemisphere is a uniform square.
    double sum = 0;
    const float lambda_o = ggx_lambda(float(wox), float(woy), float(woz), float(ax), float(ay));
    for (int i = 0; i < steps; ++i) {
        const double c2 = (i + 0.5) / steps;
        const double cos_t = std::sqrt(c2), sin_t = std::sqrt(1 - c2);
        for (int j = 0; j < steps; ++j) {
            const double phi = 2 * kPi * (j + 0.5) / steps;
            const double wix = sin_t * std::cos(phi), wiy = sin_t * std::sin(phi), wiz = cos_t;
            double hx = wix + wox, hy = wiy + woy, hz = wiz + woz;
            const double len = std::sqrt(hx * hx + hy * hy + hz * hz);
            hx /= len, hy /= len, hz /= len;
            const double d = ggx_d(float(hx), float(hy), float(hz), float(ax), float(ay));
            const double g =
                1.0 / (1.0 + lambda_o +
                       ggx_lambda(float(wix), float(wiy), float(wiz), float(ax), float(ay)));
            sum += d * g / (4 * wiz * woz);
        }
    }
    // ∫ f cosθ dω = π ∫∫ f d(cos²θ) dφ/(2π)
    return kPi * sum / (double(steps) * steps);
}

}  // namespace btf::synth
