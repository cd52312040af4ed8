// SPDX-License-Identifier: MIT
#include "btf/render/environment.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "btf/util/error.h"

namespace btf::render {

namespace {

constexpr double kTwoPi = 2 * kPi;
// Relative luminance in double precision (core's luminance() is float), Rec. 709 weights.
double luminance_double(const Rgb& c) {
    return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
}

// Validates the input and returns the 3-channel radiance × scale. `prefix` is "file: " or "".
Image prepare(Image radiance, double scale, double rotation_degrees, const std::string& prefix) {
    const int w = radiance.width(), h = radiance.height(), channels = radiance.channels();
    check(w >= 1 && h >= 1 && !radiance.empty(), "{}environment map has {} × {} pixels", prefix, w,
          h);
    check(channels == 1 || channels >= 3,
          "{}environment map has {} channels (needs 1, grey, or at least 3, RGB)", prefix,
          channels);
    check(std::isfinite(scale) && scale >= 0,
          "{}environment map scale is {} (must be finite and ≥ 0)", prefix, scale);
    check(std::isfinite(rotation_degrees), "{}environment map rotation is {} degrees", prefix,
          rotation_degrees);

    Image out(w, h, 3);
    const float s = float(scale);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                const float value = radiance.at(x, y, channels == 1 ? 0 : c);
                check(std::isfinite(value) && value >= 0,
                      "{}environment map pixel (column {}, row {}) channel {} is {} (radiance "
                      "must be finite and ≥ 0)",
                      prefix, x, y, c, value);
                const float scaled = value * s;
                check(std::isfinite(scaled),
                      "{}environment map pixel (column {}, row {}) channel {}: {} × scale {} "
                      "overflows",
                      prefix, x, y, c, value, scale);
                out.at(x, y, c) = scaled;
            }
    return out;
}

// Per-pixel weights: the mean over each pixel of the bilinear lookup's luminance (a [1 6 1] / 8
// blur, wrapping in u and repeating edge rows in v, exactly as the lookup extends the image)
// times the mean of sin θ over the pixel's row.
std::vector<double> sampling_weights(const Image& image) {
    const int w = image.width(), h = image.height();
    std::vector<double> lum(size_t(w) * h), blurred_u(size_t(w) * h), weights(size_t(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) lum[size_t(y) * w + x] = luminance_double(image.rgb(x, y));
    for (int y = 0; y < h; ++y) {
        const double* row = &lum[size_t(y) * w];
        for (int x = 0; x < w; ++x) {
            const int left = x == 0 ? w - 1 : x - 1, right = x == w - 1 ? 0 : x + 1;
            blurred_u[size_t(y) * w + x] = (row[left] + 6 * row[x] + row[right]) / 8;
        }
    }
    const double dtheta = kPi / h;
    for (int y = 0; y < h; ++y) {
        const double* up = &blurred_u[size_t(std::max(y - 1, 0)) * w];
        const double* mid = &blurred_u[size_t(y) * w];
        const double* down = &blurred_u[size_t(std::min(y + 1, h - 1)) * w];
        const double mean_sin = (std::cos(y * dtheta) - std::cos((y + 1) * dtheta)) / dtheta;
        for (int x = 0; x < w; ++x)
            weights[size_t(y) * w + x] =
                std::max((up[x] + 6 * mid[x] + down[x]) / 8 * mean_sin, 0.0);
    }
    return weights;
}

Distribution2D build_distribution(const Image& image) {
    return Distribution2D(sampling_weights(image), image.width(), image.height());
}

}  // namespace

LatLong direction_to_latlong(const Vec3& d) {
    const double horizontal = std::sqrt(d.x * d.x + d.z * d.z);
    const double theta = std::atan2(horizontal, d.y);  // accurate near the poles, unlike acos
    double phi = std::atan2(d.z, d.x);
    if (phi < 0) phi += kTwoPi;
    const double u = std::min(phi / kTwoPi, kOneMinusEpsilon), v = theta / kPi;
    if (!std::isfinite(u) || !std::isfinite(v)) return {0, 0};
    return {u, v};
}

Vec3 latlong_to_direction(double u, double v) {
    const double phi = kTwoPi * u, theta = kPi * v;
    const double sin_theta = std::sin(theta);
    return {sin_theta * std::cos(phi), std::cos(theta), sin_theta * std::sin(phi)};
}

EnvironmentMap::EnvironmentMap(Image radiance, double scale, double rotation_degrees)
    : EnvironmentMap(std::move(radiance), scale, rotation_degrees, std::string()) {}

EnvironmentMap::EnvironmentMap(Image radiance, double scale, double rotation_degrees,
                               const std::string& name)
    : m_image(prepare(std::move(radiance), scale, rotation_degrees, name)),
      m_scale(scale),
      m_rotation_degrees(rotation_degrees),
      m_cos_rotation(std::cos(radians(rotation_degrees))),
      m_sin_rotation(std::sin(radians(rotation_degrees))),
      m_distribution(build_distribution(m_image)),
      // (1/4π) ∫ Y dω = (1/4π) ∫∫ Y 2π² sin θ du dv, and the distribution's integral is the mean
      // of Y · sin θ over (u, v).
      m_average_luminance(m_distribution.integral() * kPi / 2) {}

EnvironmentMap EnvironmentMap::from_file(const std::filesystem::path& path, double scale,
                                         double rotation_degrees) {
    return EnvironmentMap(read_image(path), scale, rotation_degrees, path.string() + ": ");
}

LatLong EnvironmentMap::world_to_map(const Vec3& d) const {
    // Turning the direction by −rotation about +y gives φ_map = φ_world − rotation.
    const Vec3 local{d.x * m_cos_rotation + d.z * m_sin_rotation, d.y,
                     d.z * m_cos_rotation - d.x * m_sin_rotation};
    return direction_to_latlong(local);
}

Vec3 EnvironmentMap::map_to_world(double u, double v) const {
    const Vec3 local = latlong_to_direction(u, v);
    return {local.x * m_cos_rotation - local.z * m_sin_rotation, local.y,
            local.x * m_sin_rotation + local.z * m_cos_rotation};
}

Rgb EnvironmentMap::radiance(const Vec3& direction) const {
    const LatLong p = world_to_map(direction);
    const int w = width(), h = height();
    // Pixel centres sit at integer + 0.5; wrap around in u, clamp to the edge rows in v.
    const double fx = p.u * w - 0.5;
    const double x_floor = std::floor(fx);
    const float tx = float(fx - x_floor);
    int x0 = int(x_floor) % w;
    if (x0 < 0) x0 += w;
    const int x1 = x0 + 1 == w ? 0 : x0 + 1;
    const double fy = std::clamp(p.v * h - 0.5, 0.0, double(h - 1));
    const int y0 = std::min(int(fy), h - 1), y1 = std::min(y0 + 1, h - 1);
    const float ty = float(fy - y0);
    return m_image.rgb(x0, y0) * ((1 - tx) * (1 - ty)) + m_image.rgb(x1, y0) * (tx * (1 - ty)) +
           m_image.rgb(x0, y1) * ((1 - tx) * ty) + m_image.rgb(x1, y1) * (tx * ty);
}

double EnvironmentMap::pdf(const Vec3& direction) const {
    // The rotation about +y keeps the horizontal length, so sin θ comes from the world vector.
    const double horizontal = std::sqrt(direction.x * direction.x + direction.z * direction.z);
    const double sin_theta = horizontal / length(direction);
    if (!(sin_theta > 0)) return 0;  // also for a zero or non-finite vector
    const LatLong p = world_to_map(direction);
    return m_distribution.pdf(p.u, p.v) / (2 * kPi * kPi * sin_theta);
}

EnvSample EnvironmentMap::sample(double xi1, double xi2) const {
    const Distribution2D::Sample s = m_distribution.sample(xi1, xi2);
    const Vec3 direction = map_to_world(s.u, s.v);
    // Radiance and pdf are evaluated from the direction itself, so a renderer that later hits
    // the map along it, or asks pdf() for MIS, gets the very same numbers.
    return {direction, radiance(direction), pdf(direction)};
}

Image EnvironmentMap::make_sky(int width, int height, const Vec3& sun_direction,
                               const SkyOptions& options) {
    check(width >= 1 && height >= 1, "make_sky: size {} × {} (must be at least 1 × 1)", width,
          height);
    const double sun_length = length(sun_direction);
    check(std::isfinite(sun_length) && sun_length > 0,
          "make_sky: sun direction ({}, {}, {}) has no direction", sun_direction.x, sun_direction.y,
          sun_direction.z);
    for (const Rgb& c : {options.zenith, options.horizon, options.ground, options.sun_color})
        check(std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b) && c.r >= 0 &&
                  c.g >= 0 && c.b >= 0,
              "make_sky: colour ({}, {}, {}) must be finite and ≥ 0", c.r, c.g, c.b);
    check(options.sun_radius_degrees > 0 && options.sun_radius_degrees <= 90,
          "make_sky: sun radius {} degrees (must be in (0, 90])", options.sun_radius_degrees);
    check(options.sun_fraction >= 0 && options.sun_fraction < 1,
          "make_sky: sun fraction {} (must be in [0, 1))", options.sun_fraction);
    const double sun_colour_luminance = luminance_double(options.sun_color);
    check(options.sun_fraction == 0 || sun_colour_luminance > 0,
          "make_sky: the sun colour is black but sun fraction is {}", options.sun_fraction);

    const Vec3 sun = sun_direction / sun_length;
    const double radius = radians(options.sun_radius_degrees);
    const double cos_radius = std::cos(radius);

    auto sky = [&](double cos_theta) -> Rgb {
        if (cos_theta < 0) return options.ground;
        const double t = std::pow(1 - cos_theta, 3);
        return options.zenith * float(1 - t) + options.horizon * float(t);
    };

    // Sun radiance from the target fraction f: E_sun = f / (1 − f) · E_sky on an upward surface.
    // E_sky = 2π ∫₀¹ Y(sky(μ)) μ dμ = 2π (Y_z / 2 + (Y_h − Y_z) / 20), using ∫₀¹ (1 − μ)³ μ dμ =
    // 1/20. A cap of radius r around the sun gives ∫ cos θ dω = 2π (1 − cos r) · cos θ_sun ·
    // (1 + cos r) / 2, the cap's mean of ω·sun being (1 + cos r) / 2.
    Rgb sun_radiance{};
    if (options.sun_fraction > 0) {
        const double y_zenith = luminance_double(options.zenith),
                     y_horizon = luminance_double(options.horizon);
        const double e_sky = kTwoPi * (y_zenith / 2 + (y_horizon - y_zenith) / 20);
        const double cos_sun = std::max(sun.y, std::sin(radians(10.0)));
        const double e_sun_per_unit = kTwoPi * (1 - cos_radius) * cos_sun * (1 + cos_radius) / 2;
        const double f = options.sun_fraction;
        const double y_sun = f / (1 - f) * e_sky / e_sun_per_unit;
        sun_radiance = options.sun_color * float(y_sun / sun_colour_luminance);
    }

    Image image(width, height, 3);
    const double dtheta = kPi / height, dphi = kTwoPi / width;
    // Conservative angular distance from a pixel's centre to any point of it: along the meridian
    // half a row, then along the parallel at most half a column at the equator.
    const double pixel_reach = dtheta / 2 + dphi / 2;
    const double cos_near_sun = radius + pixel_reach < kPi ? std::cos(radius + pixel_reach) : -1;
    // At least 4 sub-samples across the sun's radius inside the pixels it touches.
    const int sun_steps = std::clamp(int(std::ceil(4 * std::max(dtheta, dphi) / radius)), 8, 256);
    constexpr int kRowSteps = 16;

    for (int y = 0; y < height; ++y) {
        // The sky depends on θ only: the solid-angle mean over the row is a 1-D quadrature.
        Rgb row_sum{};
        double row_weight = 0;
        for (int k = 0; k < kRowSteps; ++k) {
            const double theta = (y + (k + 0.5) / kRowSteps) * dtheta;
            const double weight = std::sin(theta);
            row_sum += sky(std::cos(theta)) * float(weight);
            row_weight += weight;
        }
        const Rgb row_mean = row_sum * float(1 / row_weight);
        for (int x = 0; x < width; ++x) {
            Rgb value = row_mean;
            const Vec3 centre = latlong_to_direction((x + 0.5) / width, (y + 0.5) / height);
            if (options.sun_fraction > 0 && dot(centre, sun) > cos_near_sun) {
                // Solid-angle fraction of the pixel inside the disk, on a sun_steps² grid.
                double inside = 0, total = 0;
                for (int j = 0; j < sun_steps; ++j) {
                    const double v = (y + (j + 0.5) / sun_steps) / height;
                    const double weight = std::sin(kPi * v);
                    for (int i = 0; i < sun_steps; ++i) {
                        const double u = (x + (i + 0.5) / sun_steps) / width;
                        if (dot(latlong_to_direction(u, v), sun) >= cos_radius) inside += weight;
                        total += weight;
                    }
                }
                const float coverage = total > 0 ? float(inside / total) : 0.0f;
                value = row_mean * (1 - coverage) + sun_radiance * coverage;
            }
            image.set_rgb(x, y, value);
        }
    }
    return image;
}

}  // namespace btf::render
