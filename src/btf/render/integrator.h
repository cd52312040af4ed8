// SPDX-License-Identifier: MIT
#pragma once
/// Radiance along a camera ray: unidirectional path tracing with next-event estimation and
/// multiple importance sampling (power heuristic) between light sampling and the surface's own
/// sampling, Russian roulette after a few bounces. `direct` is the same estimator stopped after
/// the first surface: next-event estimation plus the material-sampled ray's hit on an emitter.

#include <cstdint>
#include <optional>

#include "btf/render/rng.h"
#include "btf/render/scene.h"

namespace btf::render {

/// Which estimators count the light that reaches a surface directly from an emitter that paths
/// can hit (sphere lights, the environment). Delta lights are always sampled.
enum class LightStrategy {
    kMis,           ///< both, weighted by the power heuristic (the default)
    kLightOnly,     ///< next-event estimation only
    kMaterialOnly,  ///< only rays drawn by the surface's sample() that hit the emitter
};

struct IntegratorOptions {
    /// Surface interactions along a path; 1 = direct lighting only.
    int max_depth = 8;
    /// Bounces before Russian roulette may end a path.
    int roulette_depth = 3;
    LightStrategy strategy = LightStrategy::kMis;
    /// How BTF vertices filter: stochastic (one texel, view and light drawn per vertex; unbiased,
    /// and cheaper per path) or deterministic (the filtered value, every term).
    Filter filter = Filter::kStochastic;
};

/// What the first surface a camera ray meets looks like, for the AOVs.
struct FirstHit {
    bool found = false;
    Rgb albedo;
    Vec3 normal;
    Uv uv;
};

/// The stochastic filter's numbers at a path's first surface: `u` for the view and texel, `light`
/// for the lights (ShadingPoint's light_u).
struct FilterNumbers {
    double u = 0, light = 0;
};

/// One sample of the radiance arriving along `ray`; `first` (optional) receives the first hit.
/// `primary`, when given, holds the stochastic filter's numbers at the first surface (render()
/// passes stratified ones: primary_filter_numbers()); every other vertex, and the first one
/// without them, draws one number from `rng`.
Rgb radiance(const Scene& scene, const Ray& ray, Rng& rng, const IntegratorOptions& options,
             FirstHit* first = nullptr, std::optional<FilterNumbers> primary = {});

/// The stochastic filter's numbers at the first surface of sample `pass` of pixel `pixel`: two
/// Kronecker sequences over the passes, u = frac(s₁ + pass · (√5 − 1) / 2) and
/// light = frac(s₂ + pass · (√2 − 1)), from starts of the pixel's own (uniform, from the seed).
/// For one sample the two are independent uniform numbers, so the estimate stays unbiased; over
/// the first n passes of a pixel each is stratified for every n (the gaps between its values
/// take at most three sizes, the largest below 1.9 / n for u and 2.1 / n for light up to
/// n = 3000), and the pairs cover the square evenly. So the view, texel and light that the
/// visible surface draws — with weights that hardly change between a pixel's samples, the
/// light's wherever the light comes from one small source — average out faster than with
/// independent numbers.
FilterNumbers primary_filter_numbers(uint64_t seed, uint64_t pixel, uint64_t pass);

}  // namespace btf::render
