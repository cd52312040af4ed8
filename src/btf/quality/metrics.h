// SPDX-License-Identifier: MIT
#pragma once
/// Per-sample and per-image error measures between two BTFs of equal extent and sampling: RMSE and
/// PSNR in linear RGB, MAE per CIELab channel, CIEDE2000 statistics, and SSIM/MSSIM (Wang et al.
/// 2004) on luminance and on each YCrCb channel. A compressed package is compared through
/// MaterialSource. The perceptual BTF-CIELab measure, which filters across images, is in
/// btf_cielab.h. docs/quality.md gives every definition.
///
/// Conventions:
/// - RMSE, PSNR: linear RGB values as the sources hold them.
/// - CIELab (MAE and CIEDE2000): linear RGB → XYZ → CIELab with the D65 white at Y = 1 (a value
///   of 1 is the reference white, L* = 100; HDR values above 1 give L* > 100). No division by the
///   peak.
/// - SSIM: on display-encoded values: linear RGB / peak, clamped to [0, 1], sRGB transfer
///   (linear_to_srgb), then BT.601 YCbCr (rgb_to_ycbcr); dynamic range L = 1.
/// - The 95th percentile of CIEDE2000 comes from a histogram of bins kDe2000BinWidth wide over
///   [0, kDe2000HistogramMax); it is the upper edge of the bin where the cumulative share reaches
///   95% (at most the maximum), so it exceeds the exact percentile by less than one bin width.
///   Should the percentile fall above kDe2000HistogramMax, the maximum is reported.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "btf/core/color.h"
#include "btf/util/progress.h"

namespace btf {
class BtfSource;
}

namespace btf::quality {

/// CIEDE2000 of two colours (core/color.h; the batched float version is batch_colour.h's).
using btf::ciede2000;

/// Constants of the SSIM index (Wang, Bovik, Sheikh, Simoncelli 2004).
struct SsimParams {
    int window = 11;     ///< Gaussian window size (odd)
    double sigma = 1.5;  ///< Gaussian window standard deviation, pixels
    double k1 = 0.01, k2 = 0.03;
    double dynamic_range = 1;  ///< L in C1 = (K1 L)², C2 = (K2 L)²
};

/// MSSIM of two single-channel planes (row-major, `width` × `height`): the mean of the SSIM map
/// over every window position that lies fully inside the image (as the reference implementation,
/// no padding). Planes smaller than the window are compared with a window clipped to the image:
/// along such an axis the window has as many taps as the plane (the same σ, centred, renormalized)
/// and one position. Throws btf::Error on an empty plane or an even or non-positive window.
double mssim(const float* reference, const float* test, int width, int height,
             const SsimParams& params = {});

/// Resolution and range of the CIEDE2000 histogram behind Metrics::de2000_p95.
constexpr double kDe2000BinWidth = 0.01;
constexpr double kDe2000HistogramMax = 200;

/// Which measures compare() computes.
struct MetricSelection {
    bool rmse = true;    ///< RMSE and PSNR in linear RGB
    bool lab = true;     ///< MAE of L*, a*, b*
    bool de2000 = true;  ///< CIEDE2000 mean, 95th percentile, max
    bool ssim = true;    ///< MSSIM on luminance and on Y, Cr, Cb

    /// Parses a comma-separated list of "rmse", "lab", "de2000", "ssim" (other names, such as
    /// "btf-cielab", are left for the caller in `rest`). Throws btf::Error on an unknown name when
    /// `rest` is null.
    static MetricSelection parse(const std::string& list, std::vector<std::string>* rest = nullptr);

    bool any() const { return rmse || lab || de2000 || ssim; }
};

struct CompareOptions {
    MetricSelection metrics;
    /// Weight every image by cos θ of its view direction in all means and in the 95th percentile
    /// (the foreshortened area a view covers on screen); the maximum stays unweighted.
    bool cos_weight = false;
    /// Peak value for PSNR and the SSIM dynamic range; 0 picks 1 for LDR references and the
    /// largest reference value for HDR ones (SourceInfo::hdr; found by a first pass over the
    /// reference, stage "finding the peak", only when PSNR or SSIM is selected).
    double peak = 0;
    /// Keep one ImageMetrics per image in Metrics::images_detail.
    bool per_image = false;
};

/// The measures of one (view, light) image.
struct ImageMetrics {
    int view = 0, light = 0;
    double rmse = 0;
    double de2000_mean = 0;
    double ssim_luminance = 0;
};

struct Metrics {
    int64_t texels = 0;  ///< per image
    int64_t images = 0;
    double peak = 1;  ///< the peak PSNR and SSIM used
    bool cos_weighted = false;
    MetricSelection selection;  ///< the measures computed; the others stay 0

    double rmse = 0;                  ///< linear RGB, over every texel, image and channel
    double psnr = 0;                  ///< 20 log10(peak / rmse) in dB; +inf for identical inputs
    std::array<double, 3> lab_mae{};  ///< mean |ΔL*|, |Δa*|, |Δb*|
    double de2000_mean = 0, de2000_p95 = 0, de2000_max = 0;
    double ssim_luminance = 0;                ///< mean over images of the MSSIM of luminance Y
    std::array<double, 3> ssim_ycrcb{};       ///< mean over images of the MSSIM of Y, Cr, Cb
    std::vector<ImageMetrics> images_detail;  ///< when CompareOptions::per_image, image order
    double seconds = 0;
};

/// Throws btf::Error("REF vs TEST: …") naming both sources' paths when the extent or the direction
/// sets (count and directions, to 1e-4) differ.
void check_comparable(const BtfSource& reference, const BtfSource& test);

/// Reads both sources image by image (in parallel) and computes the selected measures. One
/// progress unit per image, stage "comparing". Results do not depend on the thread count: every
/// image's sums are kept and added in image order. Throws btf::Error from check_comparable(), on
/// an image of the wrong shape, or on a non-finite value (naming the source and image).
Metrics compare(const BtfSource& reference, const BtfSource& test,
                const CompareOptions& options = {}, Progress& progress = Progress::none());

}  // namespace btf::quality
