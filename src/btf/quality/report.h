// SPDX-License-Identifier: MIT
#pragma once
/// The compression report (`btf report`): a reference BTF is compressed with several codec
/// configurations, every result is decoded and compared with the reference, and a self-contained
/// HTML folder shows what each configuration costs and loses:
///
///     index.html          the page: reference facts, results table, plots, error images
///     report.json         every number of the page, for scripts (and the mark of a report folder)
///     rd-psnr.svg         rate–distortion plots drawn by btfkit (plot.h)
///     rd-btf-cielab.svg
///     colorbar-<k>.svg    the scale of the ΔE00 heat maps of selected image k (colormap.h)
///     images/<id>/…png    per configuration and selected (view, light) image: crops
///                         reference | decoded | amplified difference, and the ΔE00 heat map
///     packages/<id>.btfpkg  the encoded packages (unless keep_packages is false)
///
/// The page uses no script, no font and no network: inline CSS, relative links to files in the
/// folder. The folder is built under a temporary name beside the destination and renamed into
/// place at the end, so a failed or cancelled run leaves no partial report.

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/core/image.h"
#include "btf/io/source.h"
#include "btf/quality/btf_cielab.h"
#include "btf/quality/metrics.h"
#include "btf/util/progress.h"

namespace btf::quality {

// ---- codec configurations ----------------------------------------------------------------------

/// One codec configuration: a codec and the parameter values it is encoded with (the others keep
/// the codec's defaults).
struct CodecConfig {
    std::string codec;
    /// The codec's own parameter names (aliases resolved), in the order given.
    std::vector<std::pair<std::string, std::string>> params;

    Params to_params() const;
    /// "components=8, views-per-group=1", or "defaults" when no parameter is set.
    std::string parameters_text() const;
    /// "fmf components=8": the codec and its parameters.
    std::string label() const;
    bool operator==(const CodecConfig&) const = default;
};

/// Parses one configuration argument, `codec[:params]`, into the configurations it sweeps.
/// Parameters are comma-separated; an item with '=' starts a parameter, an item without '=' adds
/// another value to the parameter before it; several values make a sweep, and several swept
/// parameters their cartesian product (the first parameter varying slowest). Aliases: `C` is the
/// codec's `components`, `k` its `views-per-group` (pca-views). Examples: "fmf:C=8,16,32" (three
/// configurations), "pca-views:k=1,C=8", "lpca". Throws btf::Error ("codec configuration
/// 'TEXT': …") for an unknown codec or parameter (naming the known ones), a parameter given
/// twice, or a value without a parameter. Parameter values are checked by the codec when the
/// configuration is encoded.
std::vector<CodecConfig> parse_codec_configs(const std::string& text);
/// All arguments' configurations in order; throws btf::Error if one configuration appears twice.
std::vector<CodecConfig> parse_codec_configs(const std::vector<std::string>& texts);

// ---- the selected images -----------------------------------------------------------------------

/// A (view, light) image shown as crops and heat maps.
struct ReportImage {
    int view = 0, light = 0;
    std::string label;  ///< e.g. "normal view, grazing light"
    /// The directions of `view` and `light` (write_report() fills them in from the sampling).
    Direction view_direction, light_direction;
};

/// The view nearest the normal with the light nearest the normal and with the most grazing light
/// (largest θ, φ nearest 0), and the most grazing view with the frontal light; duplicates (as in a
/// sampling with a single view) are dropped.
std::vector<ReportImage> default_report_images(const Sampling& sampling);

// ---- writing a report --------------------------------------------------------------------------

/// Pixels between the three crops (reference | decoded | difference) of a crops picture.
constexpr int kCropGap = 4;

/// A render for the report's "Rendered" section and what it shows (the scene, size, samples).
struct ReportRender {
    Image image;  ///< linear radiance
    std::string caption;
    double exposure = 0;  ///< EV for display and for the comparison (the scene's)
};

struct ReportOptions {
    std::vector<CodecConfig> configs;
    /// The report folder. It must not exist, be empty, or (with `force`) hold an earlier report.
    std::filesystem::path output;
    /// Replace an existing folder that holds a btfkit report (never any other folder).
    bool force = false;
    /// Compute BTF-CIELab (the slowest measure) with these options.
    bool btf_cielab = true;
    BtfCielabOptions cielab;
    /// The images shown as crops and heat maps; empty picks default_report_images().
    std::vector<ReportImage> images;
    /// Side of the crops in texels (clipped to the image), taken from the image centre.
    int crop = 64;
    /// Amplification of the difference crop.
    double difference_gain = 4;
    /// Top of the heat-map scale in ΔE00; 0 picks, per selected image, a nice number at or above
    /// the largest 99th percentile of that image's errors over every configuration.
    double heat_max = 0;
    /// Keep the packages in packages/ (they are written there in any case and removed at the end
    /// when false).
    bool keep_packages = true;
    /// zstd level of the package sections (PackageWriteOptions).
    int zstd_level = 9;
    /// Shown at the top: the reference's name (default: its path, or its format).
    std::string reference_name;
    /// Shown at the bottom: what produced the report and how it was invoked.
    std::string generator = "btfkit";
    std::string command_line;
    /// When set, a "Rendered" section: the reference (held in memory uncompressed,
    /// SampledMaterial) and every configuration's package rendered by this function (linear
    /// radiance, the same scene, camera and seed each time), each render compared with the
    /// reference's (render_compare.h).
    std::function<ReportRender(const Material& material, Progress& progress)> render;
};

/// What the reference is (the page's header).
struct ReferenceFacts {
    std::string name, format, path, note;
    int width = 0, height = 0;
    int views = 0, lights = 0;
    std::string view_set, light_set;
    bool hdr = false;
    double raw_8bit_bytes = 0;  ///< texels × images × 3
};

/// One selected image under one configuration; file names are relative to the report folder.
struct ConfigImage {
    std::string crops, heat_map;
    double de2000_mean = 0, de2000_max = 0;
};

/// A configuration's render against the reference's (render_compare.h on display values).
struct ConfigRender {
    std::string image, heat_map;  ///< file names relative to the report folder
    double de2000_mean = 0, de2000_p95 = 0, ssim = 1, psnr = 0;
};

struct ConfigResult {
    CodecConfig config;
    std::string id;       ///< "02-fmf-components-16": names its files
    std::string package;  ///< relative path of the kept package; empty when not kept
    uint64_t bytes = 0;   ///< package file size
    double ratio = 0;     ///< raw 8-bit RGB bytes / package bytes
    double bits_per_sample =
        0;  ///< 8 · bytes / (texels · images): bits per texel per (view, light)
    double encode_seconds = 0;
    Metrics metrics;
    std::optional<BtfCielabResult> cielab;
    std::vector<ConfigImage> images;  ///< parallel to Report::images
    std::optional<ConfigRender> render;
};

struct Report {
    std::filesystem::path folder;  ///< where the report now is
    ReferenceFacts reference;
    std::vector<ReportImage> images;
    std::vector<ConfigResult> configs;
    int crop_x = 0, crop_y = 0, crop_width = 0, crop_height = 0;  ///< the crop window, texels
    double difference_gain = 4;
    std::vector<double> heat_max;  ///< per selected image: top of its heat-map scale, ΔE00
    double exposure = 1;           ///< factor applied to the crops before display (HDR references)
    bool btf_cielab = false;
    BtfCielabOptions cielab_options;
    std::string generator, command_line, created;  ///< created: UTC, ISO 8601
    /// The rendered section (ReportOptions::render): the reference's render, its caption and
    /// the heat maps' common top (ΔE00); empty when there is none.
    std::string render_reference, render_caption;
    double render_heat_max = 0;
    double render_exposure = 0;
    double seconds = 0;
};

/// Throws btf::Error if `folder` cannot receive a report: its parent folder is missing, it is a
/// file, or it is a non-empty folder and not (with `force`) an earlier btfkit report.
void check_report_output(const std::filesystem::path& folder, bool force);

/// Encodes `reference` with every configuration, measures each result (metrics.h, and BTF-CIELab
/// unless disabled) and writes the report folder. Progress: one stage per configuration and step
/// ("2/3 fmf components=16: comparing"). Throws btf::Error for a bad option or configuration
/// (naming it) and btf::Cancelled when cancelled; no report folder is then left behind.
Report write_report(const BtfSource& reference, const ReportOptions& options,
                    Progress& progress = Progress::none());

/// The page (polyglot HTML5: well-formed XML too) of a report whose files exist beside it.
std::string report_html(const Report& report);
/// Every number of the report (report.json).
nlohmann::json report_json(const Report& report);

/// What a rate–distortion plot shows against bits per sample.
enum class RdMeasure { kPsnr, kDe2000, kBtfCielab };
/// The rate–distortion plot (one series per codec, configurations in order of rate).
std::string rate_distortion_svg(const Report& report, RdMeasure measure);

}  // namespace btf::quality
