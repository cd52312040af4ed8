// SPDX-License-Identifier: MIT
#pragma once
/// Area-preserving mapping between the unit square and the upper hemisphere, and small
/// spherical-geometry helpers.
///
/// The square [0,1]² is first mapped onto the unit disk by the Shirley–Chiu concentric mapping
/// (area-preserving up to the constant factor π/4 and continuous, with bounded distortion), then
/// the disk onto the hemisphere by the Lambert azimuthal equal-area projection (z = 1 − r²,
/// sin θ = r·√(2 − r²)). Both steps preserve area up to constant factors, so every region of the
/// square maps onto a solid angle of 2π × its area: an R × R grid over the square has R² cells of
/// equal solid angle 2π / R². The square's centre is the zenith and its boundary the horizon;
/// u grows toward +x, v toward +y.
///
/// The inverse directions (hemisphere → disk → square) are inline because the angular
/// interpolator calls them once per query.

#include <algorithm>
#include <cmath>

#include "btf/core/math.h"

namespace btf {

/// A point of the unit square [0,1]².
struct SquarePoint {
    double u = 0, v = 0;
};

/// A point of the closed unit disk.
struct DiskPoint {
    double x = 0, y = 0;
};

/// Shirley–Chiu concentric mapping of [0,1]² onto the unit disk (inputs outside the square are
/// clamped to it).
DiskPoint square_to_disk(const SquarePoint& p);

/// Lambert azimuthal equal-area mapping of the unit disk onto the upper hemisphere: a disk point
/// at radius r maps to the unit vector with z = 1 − r² at the same azimuth. Points outside the
/// disk are pulled back onto its rim.
Vec3 disk_to_hemisphere(const DiskPoint& p);

/// The area-preserving map [0,1]² → upper hemisphere (unit vectors, z ≥ 0).
Vec3 square_to_hemisphere(const SquarePoint& p);

/// Inverse of disk_to_hemisphere for any vector: `d` need not be unit length; a vector below the
/// horizon is first clamped to the horizon at its azimuth (z set to 0). A vector with no such
/// direction (zero, straight down, or not finite) maps to the rim point (1, 0), i.e. +x.
inline DiskPoint hemisphere_to_disk(const Vec3& d) {
    const double z = d.z > 0 ? d.z : 0.0;  // also turns a NaN z into 0
    const double len = std::sqrt(d.x * d.x + d.y * d.y + z * z);
    if (!(len > 0) || !std::isfinite(len)) return {1, 0};
    // For a unit vector the disk point is (x, y) / √(1 + z); scaling by 1/len handles any length.
    const double s = 1.0 / std::sqrt(len * (len + z));
    return {d.x * s, d.y * s};
}

/// Inverse of square_to_disk (points outside the disk are treated as on its rim).
inline SquarePoint disk_to_square(const DiskPoint& p) {
    const double r = std::min(std::sqrt(p.x * p.x + p.y * p.y), 1.0);
    if (!(r > 0)) return {0.5, 0.5};
    constexpr double k4OverPi = 4.0 / kPi;
    double a, b;  // the square point in [-1,1]²
    if (std::abs(p.x) >= std::abs(p.y)) {
        a = p.x > 0 ? r : -r;
        b = a * k4OverPi * std::atan(p.y / p.x);
    } else {
        b = p.y > 0 ? r : -r;
        a = b * k4OverPi * std::atan(p.x / p.y);
    }
    return {std::clamp(0.5 * (a + 1), 0.0, 1.0), std::clamp(0.5 * (b + 1), 0.0, 1.0)};
}

/// Inverse of square_to_hemisphere for any vector, with the conventions of hemisphere_to_disk.
inline SquarePoint hemisphere_to_square(const Vec3& d) {
    return disk_to_square(hemisphere_to_disk(d));
}

/// Signed solid angle of the spherical triangle with unit-vector corners a, b, c (positive when
/// a, b, c run counter-clockwise seen from outside the sphere), by Van Oosterom & Strackee.
double spherical_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace btf
