// SPDX-License-Identifier: MIT
#include "btf/core/hemisphere.h"

namespace btf {

DiskPoint square_to_disk(const SquarePoint& p) {
    const double a = 2 * std::clamp(p.u, 0.0, 1.0) - 1;
    const double b = 2 * std::clamp(p.v, 0.0, 1.0) - 1;
    if (a == 0 && b == 0) return {0, 0};
    double r, phi;
    if (std::abs(a) > std::abs(b)) {
        r = a;
        phi = (kPi / 4) * (b / a);
    } else {
        r = b;
        phi = kPi / 2 - (kPi / 4) * (a / b);
    }
    return {r * std::cos(phi), r * std::sin(phi)};
}

Vec3 disk_to_hemisphere(const DiskPoint& p) {
    double x = p.x, y = p.y;
    double r2 = x * x + y * y;
    if (r2 > 1) {
        const double s = 1 / std::sqrt(r2);
        x *= s, y *= s, r2 = 1;
    }
    // Lambert: z = 1 − r², sin θ = r √(2 − r²); the disk point is scaled to length sin θ.
    const double s = std::sqrt(2 - r2);
    return {x * s, y * s, 1 - r2};
}

Vec3 square_to_hemisphere(const SquarePoint& p) {
    return disk_to_hemisphere(square_to_disk(p));
}

double spherical_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) {
    const double numerator = triple(a, b, c);
    const double denominator = 1 + dot(a, b) + dot(b, c) + dot(c, a);
    return 2 * std::atan2(numerator, denominator);
}

}  // namespace btf
