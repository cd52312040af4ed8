// SPDX-License-Identifier: MIT
#pragma once
/// The one colour module of btfkit: transfer functions and colour spaces used by readers, codecs,
/// metrics and the viewer. All RGB is linear sRGB/Rec.709 primaries with a D65 white unless a
/// function says otherwise.

#include <array>

#include "btf/core/math.h"

namespace btf {

struct Xyz {
    double x = 0, y = 0, z = 0;
};
struct Lab {
    double l = 0, a = 0, b = 0;
};

/// D65 reference white in XYZ, normalized to Y = 1.
constexpr Xyz kWhiteD65{0.95047, 1.0, 1.08883};

// ---- sRGB transfer (IEC 61966-2-1) ----
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);

// ---- linear RGB ⇄ CIE XYZ (D65) ----
Xyz rgb_to_xyz(const Rgb& rgb);
Rgb xyz_to_rgb(const Xyz& xyz);

// ---- CIE XYZ ⇄ CIELab (CIE 1976), relative to a white point ----
Lab xyz_to_lab(const Xyz& xyz, const Xyz& white = kWhiteD65);
Xyz lab_to_xyz(const Lab& lab, const Xyz& white = kWhiteD65);
inline Lab rgb_to_lab(const Rgb& rgb) {
    return xyz_to_lab(rgb_to_xyz(rgb));
}
inline Rgb lab_to_rgb(const Lab& lab) {
    return xyz_to_rgb(lab_to_xyz(lab));
}

// ---- YCbCr (ITU-R BT.601, full range, on values in [0, 1]: Cb, Cr centred at 0) ----
struct YCbCr {
    float y = 0, cb = 0, cr = 0;
};
YCbCr rgb_to_ycbcr(const Rgb& rgb);
Rgb ycbcr_to_rgb(const YCbCr& ycc);

// ---- LogLuv (Larson 1998): log2 luminance + CIE 1976 u'v' chromaticity, for HDR data ----
struct LogLuv {
    double log_y = 0;     ///< log2(Y)
    double u = 0, v = 0;  ///< CIE 1976 u', v'
};
/// Luminance must be > 0; zero luminance maps to log2 of 1e-10 with the white point's u'v'.
LogLuv xyz_to_logluv(const Xyz& xyz);
Xyz logluv_to_xyz(const LogLuv& luv);
/// XYZ of linear luminance y and chromaticity (u', v') (LogLuv without the log: y ≥ 0).
Xyz luminance_uv_to_xyz(double y, double u, double v);
inline LogLuv rgb_to_logluv(const Rgb& rgb) {
    return xyz_to_logluv(rgb_to_xyz(rgb));
}
inline Rgb logluv_to_rgb(const LogLuv& luv) {
    return xyz_to_rgb(logluv_to_xyz(luv));
}

// ---- the colour models of Bonn UBO2014 .btf files (FORMATS.md §7) ----
/// YUV with the matrices used by Bonn's btflib (analog BT.601 YUV).
std::array<float, 3> rgb_to_ubo_yuv(const Rgb& rgb);
Rgb ubo_yuv_to_rgb(const std::array<float, 3>& yuv);
/// Colour model 11: (log Y, U/Y, V/Y) with eps = 1e-5 (FORMATS.md §7).
constexpr float kUboLogEps = 1e-5f;
std::array<float, 3> rgb_to_ubo_model11(const Rgb& rgb);
Rgb ubo_model11_to_rgb(const std::array<float, 3>& c);

/// Relative luminance Y of linear RGB (Rec. 709 weights).
inline float luminance(const Rgb& c) {
    return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b;
}

/// CIEDE2000 colour difference (CIE 142-2001, as in Sharma, Wu, Dalal 2005), kL = kC = kH = 1.
double ciede2000(const Lab& a, const Lab& b);

}  // namespace btf
