// SPDX-License-Identifier: MIT
#pragma once
/// Small vector math used across btfkit (double precision for geometry).

#include <algorithm>
#include <cmath>
#include <numbers>

namespace btf {

constexpr double kPi = std::numbers::pi;

constexpr double radians(double degrees) {
    return degrees * (kPi / 180.0);
}
constexpr double degrees(double radians) {
    return radians * (180.0 / kPi);
}

struct Vec3 {
    double x = 0, y = 0, z = 0;

    constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    constexpr Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    constexpr Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
    constexpr Vec3 operator-() const { return {-x, -y, -z}; }
    constexpr Vec3& operator+=(const Vec3& o) { return *this = *this + o; }
    constexpr bool operator==(const Vec3&) const = default;
    constexpr double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};

constexpr Vec3 operator*(double s, const Vec3& v) {
    return v * s;
}
constexpr double dot(const Vec3& a, const Vec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& v) {
    return std::sqrt(dot(v, v));
}
inline Vec3 normalize(const Vec3& v) {
    return v / length(v);
}
/// det[a b c] = a · (b × c)
constexpr double triple(const Vec3& a, const Vec3& b, const Vec3& c) {
    return dot(a, cross(b, c));
}

/// Linear RGB triple (float, as stored in images).
struct Rgb {
    float r = 0, g = 0, b = 0;
    constexpr Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
    constexpr Rgb operator*(float s) const { return {r * s, g * s, b * s}; }
    constexpr Rgb& operator+=(const Rgb& o) { return *this = *this + o; }
    constexpr bool operator==(const Rgb&) const = default;
};

}  // namespace btf
