// SPDX-License-Identifier: MIT
#pragma once
// The demo scene of scripts/demo.sh as the renderer benchmarks build it (render_bench,
// filter_bench): a sphere and a cloth drape of one BTF material on a grey diffuse floor under the
// procedural sky (sun at 40°, azimuth 60°).

#include <cmath>
#include <memory>
#include <vector>

#include "btf/render/renderer.h"

namespace btf::bench {

// The demo scene of scripts/demo.sh, `width` pixels wide (3:2), the BTF on both objects.
inline btf::render::Scene demo_scene(std::shared_ptr<const btf::Material> material,
                                     btf::render::SamplingMode mode, int width) {
    using namespace btf;
    using namespace btf::render;
    Scene scene;
    scene.camera.position = {0, 1.4, 4.2};
    scene.camera.look_at = {0, 0.55, 0};
    scene.camera.fov = 30;
    scene.camera.width = width;
    scene.camera.height = width * 2 / 3;
    auto surface = std::make_shared<BtfSurface>(material, mode);
    SceneObject sphere;
    sphere.name = "sphere";
    sphere.mesh = render::make_sphere(0.55, 128);
    render::transform(sphere.mesh, Transform::translate({-0.75, 0.55, 0}));
    sphere.surface = surface;
    sphere.uv = {6, 3, 0};
    scene.add_object(std::move(sphere));
    SceneObject drape;
    drape.name = "cloth drape";
    drape.mesh = render::make_cylinder(0.45, 1.2, 128);
    render::transform(drape.mesh, Transform::translate({0.75, 0.6, 0}));
    drape.surface = surface;
    drape.uv = {5, 2, 0};
    scene.add_object(std::move(drape));
    SceneObject floor;
    floor.name = "floor";
    floor.mesh = render::make_plane(12, 12);
    floor.surface = std::make_shared<DiffuseSurface>(Rgb{0.35f, 0.35f, 0.35f});
    scene.add_object(std::move(floor));
    const double el = radians(40), az = radians(60);
    const Vec3 sun = {std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az)};
    scene.add_light(std::make_shared<EnvironmentLight>(
        std::make_shared<const EnvironmentMap>(EnvironmentMap::make_sky(1024, 512, sun))));
    scene.commit();
    return scene;
}

// Which pixels see a BTF object (object 0 or 1) through their centre.
inline std::vector<bool> btf_mask(const btf::render::Scene& scene) {
    const btf::render::Camera& c = scene.camera;
    std::vector<bool> mask(size_t(c.width) * c.height);
    for (int y = 0; y < c.height; ++y)
        for (int x = 0; x < c.width; ++x) {
            const btf::render::Hit h = scene.intersect(c.ray(x + 0.5, y + 0.5));
            mask[size_t(y) * c.width + x] = h.object == 0 || h.object == 1;
        }
    return mask;
}

/// Linear radiance of `image` against `reference` over the pixels of `mask` (btf_mask()): the
/// RMSE, the mean of `image`, and how many values (3 per pixel) entered both.
struct MaskedError {
    double rmse = 0, mean = 0, values = 0;
};
inline MaskedError masked_error(const btf::Image& image, const btf::Image& reference,
                                const std::vector<bool>& mask) {
    double squares = 0, total = 0;
    int64_t n = 0;
    for (int y = 0; y < image.height(); ++y)
        for (int x = 0; x < image.width(); ++x) {
            if (!mask[size_t(y) * image.width() + x]) continue;
            for (int c = 0; c < 3; ++c) {
                const double d = double(image.at(x, y, c)) - reference.at(x, y, c);
                squares += d * d;
                total += image.at(x, y, c);
            }
            n += 3;
        }
    return {std::sqrt(squares / double(n)), total / double(n), double(n)};
}

}  // namespace btf::bench
