// SPDX-License-Identifier: MIT
#pragma once
/// Error heat maps: a perceptual sequential colour map, error images coloured with it, and the
/// colour bar (an SVG) that states the scale.
///
/// The map is built in CIELab: lightness L* rises linearly from kColormapLightness[0] (t = 0) to
/// kColormapLightness[1] (t = 1) while the hue turns from blue-violet through cyan and green to
/// yellow (the design principle of viridis), with the chroma reduced where needed to stay inside
/// the sRGB gamut. Equal steps of the value are equal steps of lightness, the order reads without
/// colour vision, and the ends print distinctly in grey.

#include <string>
#include <vector>

#include "btf/core/image.h"
#include "btf/core/math.h"

namespace btf::quality {

/// L* of the colour map's two ends.
constexpr double kColormapLightness[2] = {22.0, 94.0};

/// The colour of `t` (clamped to [0, 1]) as linear RGB inside [0, 1].
Rgb colormap(double t);

/// "#rrggbb" of a linear RGB colour, sRGB-encoded and clamped to [0, 1].
std::string srgb_hex(const Rgb& linear);

/// A linear RGB image (width × height) colouring `values` (row-major) with colormap(value / max);
/// values above `max` take the top colour. Throws btf::Error if the sizes disagree or max <= 0.
Image heat_map(const std::vector<float>& values, int width, int height, double max);

/// A vertical colour bar from 0 (bottom) to `max` (top) with ticks on nice values, titled
/// `label`: a standalone SVG document `width` × `height` pixels.
std::string colorbar_svg(double max, const std::string& label, int width = 110, int height = 320);

/// The smallest nice number (1, 2, 2.5 or 5 times a power of ten) >= value; 1 for value <= 0.
double nice_ceil(double value);

}  // namespace btf::quality
