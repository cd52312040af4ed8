// SPDX-License-Identifier: MIT
#pragma once
/// Batched colour kernels for the per-sample work of BTF-CIELab, written as branch-free loops
/// over float arrays so that the compiler vectorizes them, math functions included (this file's
/// translation unit is built with -O3 -ffast-math, which lets GCC call glibc's vector math
/// library, libmvec). The scalar double functions (btf::xyz_to_lab, quality::ciede2000) are the
/// reference; a test holds the batches to them.

#include <array>
#include <cstdint>

#include "btf/core/math.h"

namespace btf::quality {

/// Three float planes of equal length (structure of arrays).
struct Planes {
    const float* p0;
    const float* p1;
    const float* p2;
};
struct MutablePlanes {
    float* p0;
    float* p1;
    float* p2;
};

/// Linear RGB → XYZ → LMS cone responses → lαβ (Ruderman, Cronin, Chiao 1998): LMS from XYZ by
/// the Hunt–Pointer–Estévez matrix normalized to D65 (as Reinhard et al. 2001), clamped below at
/// 1e-4 of the white (L* < 0.1) before the log10; l, α, β are the decorrelated opponent axes
/// (L+M+S)/√3, (L+M−2S)/√6, (L−M)/√2 of the log responses.
std::array<float, 3> rgb_to_opponent(const Rgb& rgb);

/// The inverse: lαβ back to cone responses and XYZ, then CIELab relative to the D65 white (Y = 1).
/// The output planes must not overlap the input planes or each other.
void opponent_to_lab(Planes opponent, MutablePlanes lab, int64_t n);

/// CIEDE2000 (kL = kC = kH = 1) of n pairs of CIELab colours, in float.
void ciede2000(Planes lab1, Planes lab2, float* out, int64_t n);

}  // namespace btf::quality
