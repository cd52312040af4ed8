// SPDX-License-Identifier: MIT
// Built with -O3 -ffast-math (see CMakeLists.txt): keep everything here free of NaN and infinity
// tests, which fast-math may remove, and of branches, which stop vectorization.

#include "btf/quality/batch_colour.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "btf/core/color.h"

namespace btf::quality {

namespace {
constexpr float kEpsilon = 216.0f / 24389.0f;  // (6/29)³
constexpr float kKappa = 24389.0f / 27.0f;     // (29/3)³
constexpr float kWhite[3] = {float(kWhiteD65.x), float(kWhiteD65.y), float(kWhiteD65.z)};

inline float lab_f(float t) {
    const float root = std::cbrt(t);  // computed unconditionally: a select, not a branch
    return t > kEpsilon ? root : (kKappa * t + 16.0f) / 116.0f;
}

constexpr double kXyzToLms[3][3] = {
    {0.3897, 0.6890, -0.0787}, {-0.2298, 1.1834, 0.0464}, {0.0, 0.0, 1.0}};
constexpr double kLmsFloor = 1e-4;

std::array<float, 9> lms_to_xyz() {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m(r, c) = kXyzToLms[r][c];
    const Eigen::Matrix3d inv = m.inverse();
    std::array<float, 9> out;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out[size_t(r * 3 + c)] = float(inv(r, c));
    return out;
}
const std::array<float, 9> kLmsToXyz = lms_to_xyz();
}  // namespace

std::array<float, 3> rgb_to_opponent(const Rgb& rgb) {
    const Xyz xyz = rgb_to_xyz(rgb);
    double lms[3];
    for (int r = 0; r < 3; ++r) {
        const double v =
            kXyzToLms[r][0] * xyz.x + kXyzToLms[r][1] * xyz.y + kXyzToLms[r][2] * xyz.z;
        lms[r] = std::log10(std::max(v, kLmsFloor));
    }
    return {float((lms[0] + lms[1] + lms[2]) / std::sqrt(3.0)),
            float((lms[0] + lms[1] - 2.0 * lms[2]) / std::sqrt(6.0)),
            float((lms[0] - lms[1]) / std::sqrt(2.0))};
}

namespace {
// GCC honours __restrict on parameters (not on local variables): with it the loop needs no
// run-time alias checks between its six arrays, which it would otherwise give up on.
void opponent_to_lab_kernel(const float* __restrict p0, const float* __restrict p1,
                            const float* __restrict p2, float* __restrict q0, float* __restrict q1,
                            float* __restrict q2, int64_t n) {
    const float k0 = kLmsToXyz[0], k1 = kLmsToXyz[1], k2 = kLmsToXyz[2], k3 = kLmsToXyz[3],
                k4 = kLmsToXyz[4], k5 = kLmsToXyz[5], k6 = kLmsToXyz[6], k7 = kLmsToXyz[7],
                k8 = kLmsToXyz[8];
    const float inv3 = 1.0f / std::sqrt(3.0f), inv6 = 1.0f / std::sqrt(6.0f),
                inv2 = 1.0f / std::sqrt(2.0f);
    for (int64_t i = 0; i < n; ++i) {
        const float a = p0[i] * inv3, b = p1[i] * inv6, c = p2[i] * inv2;
        // 10^x as exp(x·ln 10).
        const float l = std::exp((a + b + c) * 2.302585093f);
        const float m = std::exp((a + b - c) * 2.302585093f);
        const float s = std::exp((a - 2.0f * b) * 2.302585093f);
        const float x = (k0 * l + k1 * m + k2 * s) / kWhite[0];
        const float y = (k3 * l + k4 * m + k5 * s) / kWhite[1];
        const float z = (k6 * l + k7 * m + k8 * s) / kWhite[2];
        const float fx = lab_f(x), fy = lab_f(y), fz = lab_f(z);
        q0[i] = 116.0f * fy - 16.0f;
        q1[i] = 500.0f * (fx - fy);
        q2[i] = 200.0f * (fy - fz);
    }
}
}  // namespace

void opponent_to_lab(Planes in, MutablePlanes out, int64_t n) {
    opponent_to_lab_kernel(in.p0, in.p1, in.p2, out.p0, out.p1, out.p2, n);
}

void ciede2000(Planes p, Planes q, float* out, int64_t n) {
    constexpr float kPi = 3.14159265358979f, kTwoPi = 2.0f * kPi;
    constexpr float kDeg = kPi / 180.0f;
    constexpr float k25_7 = 6103515625.0f;  // 25⁷
    for (int64_t i = 0; i < n; ++i) {
        const float l1 = p.p0[i], a1 = p.p1[i], b1 = p.p2[i];
        const float l2 = q.p0[i], a2 = q.p1[i], b2 = q.p2[i];
        const float c1 = std::sqrt(a1 * a1 + b1 * b1), c2 = std::sqrt(a2 * a2 + b2 * b2);
        const float cm = 0.5f * (c1 + c2);
        const float cm7 = cm * cm * cm * cm * cm * cm * cm;
        const float g = 0.5f * (1.0f - std::sqrt(cm7 / (cm7 + k25_7)));
        const float a1p = (1.0f + g) * a1, a2p = (1.0f + g) * a2;
        const float c1p = std::sqrt(a1p * a1p + b1 * b1), c2p = std::sqrt(a2p * a2p + b2 * b2);
        float h1 = std::atan2(b1, a1p), h2 = std::atan2(b2, a2p);
        h1 = h1 < 0.0f ? h1 + kTwoPi : h1;
        h2 = h2 < 0.0f ? h2 + kTwoPi : h2;
        const float cprod = c1p * c2p;
        const bool chroma = cprod > 0.0f;

        float dh = h2 - h1;
        dh = dh > kPi ? dh - kTwoPi : (dh < -kPi ? dh + kTwoPi : dh);
        dh = chroma ? dh : 0.0f;
        const float dl = l2 - l1, dc = c2p - c1p;
        const float dhh = 2.0f * std::sqrt(cprod) * std::sin(0.5f * dh);

        const float lm = 0.5f * (l1 + l2), cmp = 0.5f * (c1p + c2p);
        const float hsum = h1 + h2;
        // Hues exactly opposite (|h1 − h2| = π) belong to the "≤ π" case; a few ulps of float
        // rounding in atan2 must not move them across (Sharma et al.'s pairs 13 and 14 test this).
        const bool far = std::fabs(h1 - h2) > kPi + 4e-6f;
        float hm =
            far ? (hsum < kTwoPi ? 0.5f * (hsum + kTwoPi) : 0.5f * (hsum - kTwoPi)) : 0.5f * hsum;
        hm = chroma ? hm : hsum;

        const float t = 1.0f - 0.17f * std::cos(hm - 30.0f * kDeg) + 0.24f * std::cos(2.0f * hm) +
                        0.32f * std::cos(3.0f * hm + 6.0f * kDeg) -
                        0.20f * std::cos(4.0f * hm - 63.0f * kDeg);
        const float dtheta_x = (hm / kDeg - 275.0f) / 25.0f;
        const float dtheta = 30.0f * kDeg * std::exp(-dtheta_x * dtheta_x);
        const float cmp7 = cmp * cmp * cmp * cmp * cmp * cmp * cmp;
        const float rc = 2.0f * std::sqrt(cmp7 / (cmp7 + k25_7));
        const float lm50 = (lm - 50.0f) * (lm - 50.0f);
        const float sl = 1.0f + 0.015f * lm50 / std::sqrt(20.0f + lm50);
        const float sc = 1.0f + 0.045f * cmp;
        const float sh = 1.0f + 0.015f * cmp * t;
        const float rt = -std::sin(2.0f * dtheta) * rc;
        const float tl = dl / sl, tc = dc / sc, th = dhh / sh;
        out[i] = std::sqrt(std::max(0.0f, tl * tl + tc * tc + th * th + rt * tc * th));
    }
}

}  // namespace btf::quality
