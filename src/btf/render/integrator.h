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

/// One sample of the radiance arriving along `ray`; `first` (optional) receives the first hit.
/// `primary_filter_number` in [0, 1), when given, is the stochastic filter's number at the first
/// surface (render() passes a stratified one: primary_filter_number()); every other vertex, and
/// the first one without it, draws its number from `rng`.
Rgb radiance(const Scene& scene, const Ray& ray, Rng& rng, const IntegratorOptions& options,
             FirstHit* first = nullptr, std::optional<double> primary_filter_number = {});

/// The stochastic filter's number at the first surface of sample `pass` of pixel `pixel`: the
/// golden-ratio sequence over the passes, frac(s + pass · (√5 − 1) / 2), from a start s of the
/// pixel's own (uniform, from the seed). Each number is uniform, so the estimate stays unbiased;
/// the first n passes of a pixel are stratified for every n (the gaps between them take at most
/// three sizes, the largest below 1.9 / n up to n = 3000), so the texel, view and light that the
/// visible surface
/// selects — with weights that hardly change between a pixel's samples — average out faster
/// than with independent numbers.
double primary_filter_number(uint64_t seed, uint64_t pixel, uint64_t pass);

}  // namespace btf::render
