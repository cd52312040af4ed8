// SPDX-License-Identifier: MIT
#include "btf/render/integrator.h"

#include <algorithm>
#include <cmath>

namespace btf::render {

namespace {

double power_heuristic(double a, double b) {
    if (!std::isfinite(a)) return 1;
    const double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0 ? a2 / (a2 + b2) : 0;
}

Rgb mul(const Rgb& a, const Rgb& b) {
    return {a.r * b.r, a.g * b.g, a.b * b.b};
}

// Nothing to carry. A stochastically filtered BTF term can be negative in every channel
// (surface.cpp): it still counts, since the terms average to the filtered value.
bool is_black(const Rgb& c) {
    return c.r == 0 && c.g == 0 && c.b == 0;
}

// The weight of an emitter reached by a material-sampled ray whose light-sampling density for
// that direction is light_pdf.
double hit_weight(LightStrategy strategy, double material_pdf, double light_pdf) {
    switch (strategy) {
        case LightStrategy::kLightOnly:
            return 0;
        case LightStrategy::kMaterialOnly:
            return 1;
        case LightStrategy::kMis:
            return power_heuristic(material_pdf, light_pdf);
    }
    return 0;
}

}  // namespace

FilterNumbers primary_filter_numbers(uint64_t seed, uint64_t pixel, uint64_t pass) {
    constexpr double kGolden = 0.61803398874989484820;  // (√5 − 1) / 2
    constexpr double kSilver = 0.41421356237309504880;  // √2 − 1
    // A stream of its own: the sample streams (seed, pixel, pass) are left as they were.
    Rng starts(seed ^ 0x5851F42D4C957F2Dull, pixel, ~uint64_t(0));
    const double s1 = starts.uniform(), s2 = starts.uniform();
    auto frac = [](double x) { return std::min(x - std::floor(x), 0x1.fffffffffffffp-1); };
    return {frac(s1 + double(pass) * kGolden), frac(s2 + double(pass) * kSilver)};
}

Rgb radiance(const Scene& scene, const Ray& camera_ray, Rng& rng, const IntegratorOptions& options,
             FirstHit* first, std::optional<FilterNumbers> primary) {
    Rgb L, beta{1, 1, 1};
    Ray ray = camera_ray;
    double previous_pdf = 0;  // the material pdf of the direction that made `ray`
    Vec3 previous_position;
    for (int depth = 0;; ++depth) {
        const Hit hit = scene.intersect(ray);
        if (!hit.found()) {
            if (const EnvironmentLight* env = scene.environment()) {
                const double w = depth == 0
                                     ? 1
                                     : hit_weight(options.strategy, previous_pdf,
                                                  env->pdf(previous_position, ray.direction));
                L += mul(beta, env->radiance(ray.direction)) * float(w);
            }
            break;
        }
        if (hit.sphere_light >= 0) {
            const SphereLight& light = *scene.sphere_lights()[size_t(hit.sphere_light)];
            const double w = depth == 0 ? 1
                                        : hit_weight(options.strategy, previous_pdf,
                                                     light.pdf(previous_position, ray.direction));
            L += mul(beta, light.radiance()) * float(w);
            break;
        }
        // Past the last interaction a path only looks for emitters (the material-sampled half of
        // direct lighting).
        if (depth >= options.max_depth) break;
        const SceneObject& object = scene.objects()[size_t(hit.object)];
        const Surface& surface = *object.surface;
        Vec3 wo = hit.to_local(-ray.direction);
        // Interpolated normals can put the viewer just below the shading horizon at silhouettes;
        // the material is defined above it.
        if (wo.z < 1e-4) wo = normalize(Vec3{wo.x, wo.y, 1e-4});
        // The vertex draws its filter term (stochastic filtering) once; every evaluation, sample
        // and density below goes through it.
        double u = 0;
        std::optional<double> light_u;
        if (options.filter == Filter::kStochastic && surface.draws_filter_number()) {
            if (depth == 0 && primary)
                u = primary->u, light_u = primary->light;
            else
                u = rng.uniform();
        }
        const Vertex vertex = surface.vertex(hit.uv, wo, options.filter, u, light_u);
        if (depth == 0 && first) {
            first->found = true;
            first->albedo = surface.albedo(vertex);
            first->normal = hit.normal;
            first->uv = hit.uv;
        }

        // Next-event estimation: one direction towards every light.
        for (const auto& light : scene.lights()) {
            const double xi1 = rng.uniform(), xi2 = rng.uniform();
            const LightDirection ld = light->sample(hit.position, xi1, xi2);
            if (!ld.delta && (!(ld.pdf > 0) || options.strategy == LightStrategy::kMaterialOnly))
                continue;
            if (is_black(ld.radiance) || dot(ld.wi, hit.geometric_normal) <= 0) continue;
            const Vec3 wi = hit.to_local(ld.wi);
            if (wi.z <= 0) continue;
            const Rgb f = surface.eval(vertex, wi);
            if (is_black(f)) continue;
            // The light sampled is not its own blocker: the shadow ray starts off the surface
            // (spawn), and from there it can meet a sphere light's surface short of the sampled
            // point by up to the offset over the cosine of incidence (near the silhouette).
            const double reach = std::isfinite(ld.distance) ? ld.distance * (1 - 1e-4) : INFINITY;
            if (scene.occluded(scene.spawn(hit, ld.wi), reach, light.get())) continue;
            double w = 1 / kPi;
            if (!ld.delta) {
                const double mis = options.strategy == LightStrategy::kMis
                                       ? power_heuristic(ld.pdf, surface.pdf(vertex, wi))
                                       : 1;
                w *= mis / ld.pdf;
            }
            L += mul(beta, mul(f, ld.radiance)) * float(w);
        }

        if (depth + 1 >= options.max_depth && !scene.environment() && scene.sphere_lights().empty())
            break;  // no emitter a further ray could reach
        const double xi1 = rng.uniform(), xi2 = rng.uniform();
        const LightSample s = surface.sample(vertex, xi1, xi2);
        if (!(s.pdf > 0) || is_black(s.weight)) break;
        const Vec3 wi = hit.to_world(s.wi);
        if (dot(wi, hit.geometric_normal) <= 0) break;  // would leave through the surface
        beta = mul(beta, s.weight * float(1 / kPi));
        previous_pdf = s.pdf;
        previous_position = hit.position;
        ray = scene.spawn(hit, wi);
        if (depth + 1 >= options.roulette_depth) {
            const double q = std::min(
                0.95, double(std::max({std::abs(beta.r), std::abs(beta.g), std::abs(beta.b)})));
            if (rng.uniform() >= q) break;
            beta = beta * float(1 / q);
        }
    }
    return L;
}

}  // namespace btf::render
