// SPDX-License-Identifier: MIT
#include "btf/core/color.h"

#include <algorithm>
#include <cmath>

namespace btf {

float srgb_to_linear(float e) {
    if (e <= 0.04045f) return e / 12.92f;
    return std::pow((e + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float l) {
    if (l <= 0.0031308f) return 12.92f * l;
    return 1.055f * std::pow(l, 1.0f / 2.4f) - 0.055f;
}

// sRGB primaries with the D65 white (IEC 61966-2-1), derived to 7 decimals; the two matrices are
// inverses of each other to about 1e-7.
namespace {
constexpr double kRgbToXyz[3][3] = {{0.4124564, 0.3575761, 0.1804375},
                                    {0.2126729, 0.7151522, 0.0721750},
                                    {0.0193339, 0.1191920, 0.9503041}};
constexpr double kXyzToRgb[3][3] = {{3.2404542, -1.5371385, -0.4985314},
                                    {-0.9692660, 1.8760108, 0.0415560},
                                    {0.0556434, -0.2040259, 1.0572252}};
}  // namespace

Xyz rgb_to_xyz(const Rgb& c) {
    const double r = c.r, g = c.g, b = c.b;
    return {kRgbToXyz[0][0] * r + kRgbToXyz[0][1] * g + kRgbToXyz[0][2] * b,
            kRgbToXyz[1][0] * r + kRgbToXyz[1][1] * g + kRgbToXyz[1][2] * b,
            kRgbToXyz[2][0] * r + kRgbToXyz[2][1] * g + kRgbToXyz[2][2] * b};
}

Rgb xyz_to_rgb(const Xyz& c) {
    return {float(kXyzToRgb[0][0] * c.x + kXyzToRgb[0][1] * c.y + kXyzToRgb[0][2] * c.z),
            float(kXyzToRgb[1][0] * c.x + kXyzToRgb[1][1] * c.y + kXyzToRgb[1][2] * c.z),
            float(kXyzToRgb[2][0] * c.x + kXyzToRgb[2][1] * c.y + kXyzToRgb[2][2] * c.z)};
}

namespace {
constexpr double kLabEpsilon = 216.0 / 24389.0;  // (6/29)^3
constexpr double kLabKappa = 24389.0 / 27.0;     // (29/3)^3

double lab_f(double t) {
    return t > kLabEpsilon ? std::cbrt(t) : (kLabKappa * t + 16.0) / 116.0;
}
double lab_f_inv(double f) {
    const double f3 = f * f * f;
    return f3 > kLabEpsilon ? f3 : (116.0 * f - 16.0) / kLabKappa;
}
}  // namespace

Lab xyz_to_lab(const Xyz& c, const Xyz& w) {
    const double fx = lab_f(c.x / w.x), fy = lab_f(c.y / w.y), fz = lab_f(c.z / w.z);
    return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

Xyz lab_to_xyz(const Lab& c, const Xyz& w) {
    const double fy = (c.l + 16.0) / 116.0;
    const double fx = fy + c.a / 500.0;
    const double fz = fy - c.b / 200.0;
    const double yr = c.l > kLabKappa * kLabEpsilon ? fy * fy * fy : c.l / kLabKappa;
    return {lab_f_inv(fx) * w.x, yr * w.y, lab_f_inv(fz) * w.z};
}

YCbCr rgb_to_ycbcr(const Rgb& c) {
    const float y = 0.299f * c.r + 0.587f * c.g + 0.114f * c.b;
    return {y, (c.b - y) / 1.772f, (c.r - y) / 1.402f};
}

Rgb ycbcr_to_rgb(const YCbCr& c) {
    const float r = c.y + 1.402f * c.cr;
    const float b = c.y + 1.772f * c.cb;
    const float g = (c.y - 0.299f * r - 0.114f * b) / 0.587f;
    return {r, g, b};
}

namespace {
constexpr double kMinLuminance = 1e-10;
}

LogLuv xyz_to_logluv(const Xyz& c) {
    const double denom = c.x + 15.0 * c.y + 3.0 * c.z;
    if (!(c.y > kMinLuminance) || !(denom > 0)) {
        const double wd = kWhiteD65.x + 15.0 * kWhiteD65.y + 3.0 * kWhiteD65.z;
        return {std::log2(kMinLuminance), 4.0 * kWhiteD65.x / wd, 9.0 * kWhiteD65.y / wd};
    }
    return {std::log2(c.y), 4.0 * c.x / denom, 9.0 * c.y / denom};
}

Xyz logluv_to_xyz(const LogLuv& c) {
    return luminance_uv_to_xyz(std::exp2(c.log_y), c.u, c.v);
}

Xyz luminance_uv_to_xyz(double y, double u, double v) {
    if (!(v > 0)) return {0, y, 0};
    const double x = y * 9.0 * u / (4.0 * v);
    const double z = y * (12.0 - 3.0 * u - 20.0 * v) / (4.0 * v);
    return {x, y, z};
}

// btflib's YUV: Y = 0.299 R + 0.587 G + 0.114 B, U = 0.492 (B − Y), V = 0.877 (R − Y); its inverse
// is the matrix FORMATS.md quotes: R = Y + 1.13983 V, G = Y − 0.39465 U − 0.58060 V,
// B = Y + 2.03211 U.
std::array<float, 3> rgb_to_ubo_yuv(const Rgb& c) {
    const float y = 0.299f * c.r + 0.587f * c.g + 0.114f * c.b;
    const float u = -0.14713f * c.r - 0.28886f * c.g + 0.436f * c.b;
    const float v = 0.615f * c.r - 0.51499f * c.g - 0.10001f * c.b;
    return {y, u, v};
}

Rgb ubo_yuv_to_rgb(const std::array<float, 3>& yuv) {
    const float y = yuv[0], u = yuv[1], v = yuv[2];
    return {y + 1.13983f * v, y - 0.39465f * u - 0.58060f * v, y + 2.03211f * u};
}

std::array<float, 3> rgb_to_ubo_model11(const Rgb& c) {
    const auto yuv = rgb_to_ubo_yuv(c);
    const float y = std::max(yuv[0], 0.0f);
    return {std::log(y + kUboLogEps), yuv[1] / (y + kUboLogEps), yuv[2] / (y + kUboLogEps)};
}

Rgb ubo_model11_to_rgb(const std::array<float, 3>& c) {
    const float y = std::exp(c[0]) - kUboLogEps;
    return ubo_yuv_to_rgb({y, c[1] * (y + kUboLogEps), c[2] * (y + kUboLogEps)});
}

// ---- CIEDE2000 (the metrics and the factorization codecs' size choice both use it)
// ---------------

namespace {
constexpr double kPow25To7 = 6103515625.0;  // 25^7
const double kCos30 = std::cos(radians(30)), kSin30 = std::sin(radians(30));
const double kCos6 = std::cos(radians(6)), kSin6 = std::sin(radians(6));
const double kCos63 = std::cos(radians(63)), kSin63 = std::sin(radians(63));

double pow7(double x) {
    const double x2 = x * x;
    return x2 * x2 * x2 * x;
}

// Hue angle in degrees, [0, 360); 0 for the achromatic axis (Sharma et al., eq. 7).
double hue_degrees(double b, double a_prime) {
    if (b == 0 && a_prime == 0) return 0;
    const double h = degrees(std::atan2(b, a_prime));
    return h < 0 ? h + 360 : h;
}
}  // namespace

double ciede2000(const Lab& lab1, const Lab& lab2) {
    // Step 1: a' scaling by G, from the mean chroma of the two colours.
    const double c1 = std::sqrt(lab1.a * lab1.a + lab1.b * lab1.b);
    const double c2 = std::sqrt(lab2.a * lab2.a + lab2.b * lab2.b);
    const double c_mean7 = pow7(0.5 * (c1 + c2));
    const double g = 0.5 * (1 - std::sqrt(c_mean7 / (c_mean7 + kPow25To7)));
    const double a1 = (1 + g) * lab1.a, a2 = (1 + g) * lab2.a;
    const double cp1 = std::sqrt(a1 * a1 + lab1.b * lab1.b);
    const double cp2 = std::sqrt(a2 * a2 + lab2.b * lab2.b);
    const double h1 = hue_degrees(lab1.b, a1), h2 = hue_degrees(lab2.b, a2);

    // Step 2: differences. A zero chroma makes the hue undefined: Δh' = 0 (eq. 10).
    const double dl = lab2.l - lab1.l;
    const double dc = cp2 - cp1;
    const double cp_product = cp1 * cp2;
    double dh = 0;
    if (cp_product != 0) {
        dh = h2 - h1;
        if (dh > 180)
            dh -= 360;
        else if (dh < -180)
            dh += 360;
    }
    const double dh_big = 2 * std::sqrt(cp_product) * std::sin(radians(dh / 2));

    // Step 3: means and weighting functions. The mean hue takes the short way round the circle
    // and is the plain sum when a chroma is zero (eq. 14).
    const double l_mean = 0.5 * (lab1.l + lab2.l);
    const double cp_mean = 0.5 * (cp1 + cp2);
    double h_mean = h1 + h2;
    if (cp_product != 0) {
        if (std::abs(h1 - h2) <= 180)
            h_mean = 0.5 * (h1 + h2);
        else if (h1 + h2 < 360)
            h_mean = 0.5 * (h1 + h2 + 360);
        else
            h_mean = 0.5 * (h1 + h2 - 360);
    }
    // T from one sine and cosine of h̄': those of 2h̄', 3h̄', 4h̄' by angle addition.
    const double hr = radians(h_mean);
    const double cs1 = std::cos(hr), sn1 = std::sin(hr);
    const double cs2 = cs1 * cs1 - sn1 * sn1, sn2 = 2 * sn1 * cs1;
    const double cs3 = cs2 * cs1 - sn2 * sn1, sn3 = sn2 * cs1 + cs2 * sn1;
    const double cs4 = cs2 * cs2 - sn2 * sn2, sn4 = 2 * sn2 * cs2;
    const double t = 1 - 0.17 * (cs1 * kCos30 + sn1 * kSin30)  // cos(h̄' − 30°)
                     + 0.24 * cs2                              // cos(2h̄')
                     + 0.32 * (cs3 * kCos6 - sn3 * kSin6)      // cos(3h̄' + 6°)
                     - 0.20 * (cs4 * kCos63 + sn4 * kSin63);   // cos(4h̄' − 63°)
    const double hue_offset = (h_mean - 275) / 25;
    const double d_theta = 30 * std::exp(-hue_offset * hue_offset);
    const double cp_mean7 = pow7(cp_mean);
    const double r_c = 2 * std::sqrt(cp_mean7 / (cp_mean7 + kPow25To7));
    const double l50 = (l_mean - 50) * (l_mean - 50);
    const double s_l = 1 + 0.015 * l50 / std::sqrt(20 + l50);
    const double s_c = 1 + 0.045 * cp_mean;
    const double s_h = 1 + 0.015 * cp_mean * t;
    const double r_t = -std::sin(radians(2 * d_theta)) * r_c;

    const double tl = dl / s_l, tc = dc / s_c, th = dh_big / s_h;
    return std::sqrt(std::max(0.0, tl * tl + tc * tc + th * th + r_t * tc * th));
}

}  // namespace btf
