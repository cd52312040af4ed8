// SPDX-License-Identifier: MIT
#pragma once
/// The 6-D BTF lookup every evaluator shares: bilinear in space (wrapping) × barycentric over
/// ≤ 3 views × barycentric over ≤ 3 lights.

#include <cmath>

#include "btf/core/angular_interpolator.h"
#include "btf/core/material.h"
#include "btf/core/math.h"

namespace btf {

/// The two texels and the blend factor of a wrapping linear interpolation along one axis.
struct WrapLerp {
    int i0 = 0;   ///< first texel, in [0, size)
    int i1 = 0;   ///< second texel, (i0 + 1) mod size
    float t = 0;  ///< weight of i1; i0 has weight 1 − t
};

/// Linear interpolation with texel centres at (i + 0.5) / size over the coordinate `c` (in
/// texture units, wrapping with period 1). A non-finite `c` counts as 0.
inline WrapLerp wrap_lerp(double c, int size) {
    double x = c * size - 0.5;
    if (!std::isfinite(x)) x = -0.5;
    if (!(x >= 0 && x < size)) x -= size * std::floor(x / size);  // in [0, size) up to rounding
    if (!(x >= 0 && x < size)) x = 0;  // rounding for huge |c|, or exactly size
    const int i0 = static_cast<int>(x);
    const double t = x - i0;
    return {i0, i0 + 1 == size ? 0 : i0 + 1, static_cast<float>(t)};
}

/// Spatially bilinear (wrapping, texel centres at (x + 0.5) / width) × views × lights:
/// Σ_v Σ_l w_v w_l Σ_4 bilinear · fetch(x, y, view, light), fetch returning Rgb.
/// `fetch(x, y, view, light)` receives texel coordinates in [0, width) × [0, height) and indices
/// from `views` and `lights`; it is called only for pairs with non-zero weight.
template <typename Fetch>
Rgb lookup6d(const Uv& uv, int width, int height, const AngularWeights& views,
             const AngularWeights& lights, Fetch&& fetch) {
    const WrapLerp lx = wrap_lerp(uv.u, width);
    const WrapLerp ly = wrap_lerp(uv.v, height);
    const float w00 = (1 - lx.t) * (1 - ly.t), w10 = lx.t * (1 - ly.t);
    const float w01 = (1 - lx.t) * ly.t, w11 = lx.t * ly.t;
    Rgb sum;
    for (int v = 0; v < views.count; ++v) {
        const float wv = views.weight[v];
        if (wv == 0) continue;
        const int view = views.index[v];
        for (int l = 0; l < lights.count; ++l) {
            const float w = wv * lights.weight[l];
            if (w == 0) continue;
            const int light = lights.index[l];
            Rgb s = fetch(lx.i0, ly.i0, view, light) * w00;
            s += fetch(lx.i1, ly.i0, view, light) * w10;
            s += fetch(lx.i0, ly.i1, view, light) * w01;
            s += fetch(lx.i1, ly.i1, view, light) * w11;
            sum += s * w;
        }
    }
    return sum;
}

}  // namespace btf
