// SPDX-License-Identifier: MIT
#pragma once
/// An infinite area light from a latitude-longitude ("equirectangular") radiance image, with
/// importance sampling of its directions, and a procedural sky to light scenes without a file.
///
/// Convention (right-handed world, +y up). A direction d in the map's own frame has
///     φ = atan2(d.z, d.x) wrapped to [0, 2π),   θ = acos(d.y)   (θ = 0 is straight up),
/// and lies at image coordinates
///     u = φ / 2π   (column u · width,  u = 0 is +x, u = 1/4 is +z, u = 1/2 is −x),
///     v = θ / π    (row v · height: row 0 is the zenith, the last row the nadir).
/// Pixel (column c, row r) covers u in [c, c+1) / width and v in [r, r+1) / height; its value
/// is the radiance at its centre. The map's frame is the world's turned about +y by
/// `rotation_degrees`: the map content seen at world azimuth φ_world is that at
///     φ_map = φ_world − rotation,
/// so a positive rotation moves the content toward larger φ (from +x toward +z). Seen from above
/// (looking down −y) in this right-handed frame that is a clockwise turn of the content; seen from
/// below, counter-clockwise. With rotation 0 map and world frames coincide.
///
/// Radiance lookup is bilinear between pixel centres, wrapping around in u (the seam at φ = 0 is
/// continuous) and clamped in v (within half a pixel of a pole the first or last row is constant
/// along v).
///
/// Importance sampling draws directions with a density proportional to a piecewise-constant
/// (per pixel, in u and v) approximation of luminance × sin θ, where sin θ is the Jacobian of the
/// (u, v) → direction map (dω = 2π² sin θ du dv). The per-pixel value is the exact mean of the
/// *bilinear* radiance over the pixel: a separable [1 6 1] / 8 blur of the pixel luminances
/// (wrapping in u, repeating the edge rows in v, as the lookup does), times the mean of sin θ over
/// the pixel's rows. Because that blur reaches every neighbour that the bilinear lookup mixes in,
/// pdf() > 0 wherever radiance() > 0, and the distribution's total equals the integral of the
/// lookup's luminance up to the variation of sin θ inside a pixel. A pixel whose blurred luminance
/// is 0 is never sampled; a map that is black everywhere is sampled uniformly in (u, v).
///
/// All const methods are deterministic and thread-safe.

#include <filesystem>
#include <string>

#include "btf/core/image.h"
#include "btf/core/math.h"
#include "btf/render/distribution.h"

namespace btf::render {

/// Latitude-longitude coordinates of a direction: u = φ / 2π in [0, 1), v = θ / π in [0, 1].
struct LatLong {
    double u = 0, v = 0;
};

/// (u, v) of a direction in the map's frame (see the file comment). `direction` need not be unit
/// length; a zero or non-finite vector maps to (0, 0).
LatLong direction_to_latlong(const Vec3& direction);
/// The unit direction in the map's frame at (u, v); the inverse of direction_to_latlong().
Vec3 latlong_to_direction(double u, double v);

/// A direction drawn from an environment map.
struct EnvSample {
    Vec3 direction;  ///< unit vector toward the light, in world space
    Rgb radiance;    ///< radiance(direction): what a ray leaving along `direction` would see
    double pdf = 0;  ///< density per unit solid angle, pdf(direction); 0 at the poles
};

/// Parameters of EnvironmentMap::make_sky(). Radiances are linear Rec. 709 RGB.
struct SkyOptions {
    /// Sky radiance straight up.
    Rgb zenith{0.10f, 0.22f, 0.60f};
    /// Sky radiance just above the horizon. Between the two the sky is
    /// zenith + (horizon − zenith) · (1 − cos θ)³: the horizon's brighter, paler colour fades
    /// quickly into the zenith's deeper blue.
    Rgb horizon{0.60f, 0.70f, 0.85f};
    /// Radiance of every direction below the horizon (a uniform brown ground).
    Rgb ground{0.12f, 0.08f, 0.05f};
    /// Colour of the sun disk; only its chromaticity matters (it is rescaled to luminance 1).
    Rgb sun_color{1.0f, 0.92f, 0.80f};
    /// Angular radius of the sun disk in degrees, in (0, 90].
    double sun_radius_degrees = 2.5;
    /// Fraction of the luminance irradiance on an upward-facing surface that comes from the sun,
    /// in [0, 1); it sets the sun's radiance. For a sun lower than 10° above the horizon (or below
    /// it) the radiance of a sun at 10° is used, so the sun stays finite. 0 draws no sun.
    double sun_fraction = 0.8;
};

/// An infinite light from a latitude-longitude radiance image (see the file comment for the
/// convention and the sampling strategy).
class EnvironmentMap {
  public:
    /// `radiance` holds linear radiance: one channel (grey) or at least three (the first three
    /// are RGB, further ones are ignored). Every value is multiplied by `scale`. Throws btf::Error
    /// for an empty image, two channels, a negative or non-finite value, or a negative or
    /// non-finite scale or rotation.
    explicit EnvironmentMap(Image radiance, double scale = 1, double rotation_degrees = 0);
    /// Reads the radiance image with read_image() (EXR, HDR, ...; 8-bit files are decoded from
    /// sRGB). Errors name the file, e.g. "sky.exr: environment map has 0 × 0 pixels".
    static EnvironmentMap from_file(const std::filesystem::path& path, double scale = 1,
                                    double rotation_degrees = 0);

    int width() const { return m_image.width(); }
    int height() const { return m_image.height(); }
    double scale() const { return m_scale; }
    double rotation_degrees() const { return m_rotation_degrees; }
    /// The radiance image, three channels, already multiplied by scale().
    const Image& image() const { return m_image; }

    /// (u, v) in the image of a world-space direction (rotation applied).
    LatLong world_to_map(const Vec3& direction) const;
    /// The unit world-space direction at image coordinates (u, v) (rotation applied).
    Vec3 map_to_world(double u, double v) const;

    /// Radiance arriving from world-space `direction` (need not be unit length), bilinear.
    Rgb radiance(const Vec3& direction) const;
    /// Draws a direction with density pdf(); ξ1 chooses u (azimuth), ξ2 chooses v (polar angle).
    /// The map ξ → direction is continuous inside each pixel.
    EnvSample sample(double xi1, double xi2) const;
    /// Density per unit solid angle with which sample() draws world-space `direction`:
    /// pdf_uv(u, v) / (2π² sin θ), and 0 where sin θ = 0.
    double pdf(const Vec3& direction) const;
    /// Mean luminance over the sphere, (1/4π) ∫ Y(radiance(ω)) dω, from the same per-pixel
    /// values the sampling distribution uses. 4π × this is the light's luminance power per unit
    /// area of a receiver; 0 for a black map.
    double average_luminance() const { return m_average_luminance; }

    /// A procedural HDR sky of width × height pixels in this convention (map frame): a smooth
    /// gradient from a bright pale horizon to a deep blue zenith, a dimmer brown ground below the
    /// horizon, and a bright sun disk centred on `sun_direction` (any length > 0). Each pixel is
    /// the solid-angle mean over the pixel (the horizon and the sun's rim are antialiased), so
    /// the sun's power barely depends on the resolution. Deterministic. Throws btf::Error for a
    /// size below 1 × 1, a zero or non-finite sun direction or invalid options.
    static Image make_sky(int width, int height, const Vec3& sun_direction,
                          const SkyOptions& options = {});

  private:
    EnvironmentMap(Image radiance, double scale, double rotation_degrees, const std::string& name);

    Image m_image;
    double m_scale = 1, m_rotation_degrees = 0;
    double m_cos_rotation = 1, m_sin_rotation = 0;
    Distribution2D m_distribution;
    double m_average_luminance = 0;
};

}  // namespace btf::render
