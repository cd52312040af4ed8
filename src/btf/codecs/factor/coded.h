// SPDX-License-Identifier: MIT
#pragma once
/// Coded factor storage (`quantize=coded`): each component section holds its angular factor a
/// and its texel factor b quantized with steps chosen from one value-domain step Δ, and
/// entropy-coded along their structure (docs/formats.md, "Coded components").
///
/// The steps are a reverse water-filling: component k's b is quantized with Δ / rms(a_k) and its
/// a with κ Δ / rms(b_k) (kAngularStepScale), so that each side's rounding adds an error to the
/// values that does not depend on the component's energy (Δ²/12 per sample from b, κ² times that
/// from a, where a coefficient is not zeroed); the components and coefficients too weak for Δ are
/// left out by the quantizer (they cost one short code each). Δ comes from `quality` Q ∈ [0,
/// 100]: Δ = 2^(−Q/10) · the RMS of the model's values, so each 10 more halves the step.
///
/// a: uniform rounding, coded as differences to the value `stride` rows before (the same
/// channel of the previous light), or for rows of 3 channels by channel prediction (the middle
/// channel as differences along the rows, the outer ones as differences of their offsets to the
/// middle one: a component's colour changes slowly over the directions), or where the rows'
/// layout over views and lights is known (AngularRows) by neighbouring directions (the same
/// planes, each predicted by the mean of the previous light's and the previous view's: a is
/// smooth over both), or as images of directions (each plane an image of views × lights, coded
/// like b's images below but mirrored past its edges; its dead zone drops angular detail a weak
/// component cannot pay for), whichever has the least squared error plus λ times its bits (λ the
/// slope of the balanced quantizer; among the rounded predictions, the shortest). b: where b is
/// an image (W
/// × H texels of a level, one cluster), 8 × 8 DCT blocks of the image extended periodically to a
/// multiple of 8 (the evaluator wraps around the edges), quantized with a dead zone (|c|/step +
/// 1/3, rounded down: coefficients under 2/3 of a step become 0) and written band by band (every
/// block's first coefficient in zig-zag order, as differences along the blocks, then every block's
/// second, …); elsewhere (lpca's clusters) uniform rounding with differences like a. The
/// integers are written with an adaptive binary range coder (util/range_coder.h), whose contexts
/// separate a's streams, the images' DC differences and bands by zig-zag diagonal (a's apart
/// from b's; format 2), or as
/// zig-zag varints for the container's zstd (format 1, distances only), whichever is shorter
/// after zstd: zstd's matches find repeated runs the coder's adaptive models miss. Decoded values
/// are rounded to half floats (so the evaluator keeps half rows, as for f16): a further relative
/// error of at most 2⁻¹¹.

#include <cstdint>
#include <string_view>
#include <vector>

#include "btf/codecs/factor/angular_levels.h"

namespace btf::factor::coded {

constexpr uint8_t kFormat = 2;        ///< range-coded integers
constexpr uint8_t kVarintFormat = 1;  ///< varints, for the container's zstd
/// Each section is written in the format that is shorter after zstd at this level (the
/// container's default).
constexpr int kZstdLevelForChoice = 9;

/// One column of a factor: n values, `stride` floats apart.
struct Column {
    float* data;
    int64_t n, stride;
};
struct ConstColumn {
    const float* data;
    int64_t n, stride;
};

/// The texel factor's shape: an image of width × height texels (n = width · height), or
/// width = height = 0 for values without a neighbourhood.
struct Image {
    int width = 0, height = 0;
};

/// The layout of a's rows: `channels` values for each (view, light) pair, `lights` pairs per view
/// (rows (view · lights + light) · channels + channel). Unknown (0): a is predicted along its rows
/// only.
struct AngularRows {
    int64_t lights = 0;
    int channels = 0;
};

/// a's step is this fraction of the one that would make its rounding add as much squared error as
/// b's (Δ / rms(b)): an error in a is a colour error (a holds each component's colour over the
/// directions; b is one number per texel) and shifts whole images alike, which the mean CIEDE2000
/// rates above b's. A compromise measured at equal package size on four materials against 1, 0.5
/// and 0.25 (docs/benchmarks.md, "Rate–distortion with coded factors"): no single value is best
/// on all of them.
constexpr double kAngularStepScale = 0.35;

/// Value-domain step for `quality` and the RMS of the values (see above).
double value_step(double quality, double rms);

/// Appends the coded section of one component. With `up` (a component of an angular level), a
/// holds the level's values, which count as their up-sampling U a: b's step is Δ over the RMS of
/// U a, and a's is Δ / rms(b) over the square root of the mean weight of a stored value in U
/// a (‖U‖²_F over the stored values; about the full directions per stored one), so that either
/// side's rounding still adds about Δ²/12 per full value.
void put_component(std::vector<uint8_t>& out, ConstColumn a, ConstColumn b, Image image,
                   double step, const AngularResampler* up = nullptr, AngularRows rows = {});
/// Decodes a section written by put_component into a and b (whose n, image and rows must be those
/// it was written with); throws btf::Error "section '<name>': …" for a damaged or foreign payload.
void get_component(const uint8_t* data, size_t size, Column a, Column b, Image image,
                   std::string_view name, AngularRows rows = {});

/// The largest error of a decoded value of a DCT-coded image (b, or a plane of a as images of
/// directions, whose outer channels add the middle one's error to their offset's): every one of
/// the 64 coefficients of its block off by at most 2/3 of a step (the dead zone), each weighted by
/// at most 1/4 (the largest value of a product of two 8-point orthonormal DCT basis functions):
/// 64 · 2/3 · 1/4 · step.
constexpr double kImageErrorPerStep = 64.0 * 2.0 / 3.0 / 4.0;

}  // namespace btf::factor::coded
