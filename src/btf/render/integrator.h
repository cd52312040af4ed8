#pragma once
/// Radiance along a camera ray: unidirectional path tracing with next-event estimation and
/// multiple importance sampling (power heuristic) between light sampling and the surface's own
/// sampling, Russian roulette after a few bounces. `direct` is the same estimator stopped after
/// the first surface: next-event estimation plus the material-sampled ray's hit on an emitter.

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
Rgb radiance(const Scene& scene, const Ray& ray, Rng& rng, const IntegratorOptions& options,
             FirstHit* first = nullptr);

}  // namespace btf::render
