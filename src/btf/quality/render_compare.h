// SPDX-License-Identifier: MIT
#pragma once
/// How different two renders of one scene look: the compare mode of `btf render`, which renders a
/// scene with two versions of a material (raw and compressed, or two codec settings) so that a
/// user can judge whether the difference matters on an object under real light.
///
/// Measured on what a display shows: both images tone-mapped with the same exposure (tone_map()),
/// then
///  - CIEDE2000 per pixel between the tone-mapped values taken as linear RGB with white = 1
///    (mean and 95th percentile), the heat map's quantity;
///  - MSSIM of the sRGB-encoded luminance (Rec. 709 Y of the tone-mapped values), window 11, σ 1.5;
///  - PSNR of the tone-mapped RGB values (peak 1).

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "btf/core/image.h"

namespace btf::quality {

struct RenderComparison {
    double de2000_mean = 0, de2000_p95 = 0;
    double ssim = 1;
    double psnr = 0;            ///< dB; infinite for identical images
    std::vector<float> de2000;  ///< per pixel, row-major
    Image heat_map;             ///< de2000 through the report's colour map, 0 … heat_max
    double heat_max = 0;
};

/// ACES filmic curve (Narkowicz's fit) after scaling by 2^exposure: linear radiance to display
/// values in [0, 1], still linear (write_image() applies the sRGB transfer for PNG).
Image tone_map(const Image& linear, double exposure = 0);

/// Compares two linear renders of equal size: compare_displays() of their tone_map()s.
/// `heat_max` ≤ 0 picks a round maximum above the 99th percentile of ΔE00. Throws btf::Error if
/// the sizes differ.
RenderComparison compare_renders(const Image& a, const Image& b, double exposure = 0,
                                 double heat_max = 0);

/// Compares two pictures as a display shows them: display values in [0, 1], linear (an 8-bit
/// sRGB file read with read_image(), or tone_map() of a render). Throws btf::Error if the sizes
/// differ.
RenderComparison compare_displays(const Image& a_display, const Image& b_display,
                                  double heat_max = 0);

/// The comparison's numbers as JSON: de2000_mean, de2000_p95, ssim, psnr_db (null when the
/// images are identical) and heat_map_max.
nlohmann::json metrics_json(const RenderComparison& c);
/// "ΔE00 mean 0.363, 95th percentile 0.780; SSIM 0.9899; PSNR 40.73 dB".
std::string summary(const RenderComparison& c);

/// A, B and the heat map side by side, separated by 4-pixel gaps (display values).
Image side_by_side(const Image& a_display, const Image& b_display, const Image& heat_map);

}  // namespace btf::quality
