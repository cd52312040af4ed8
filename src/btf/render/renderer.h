// SPDX-License-Identifier: MIT
#pragma once
/// The render loop: passes of one sample per pixel over tiles rendered in parallel on all cores,
/// until the requested samples per pixel or the time limit is reached; the image, optional AOVs
/// and the output files (linear EXR, tone-mapped sRGB PNG).
///
/// Determinism: sample s of pixel p draws its random numbers from the stream (seed, p, s), so an
/// image rendered to N samples per pixel is the same for any thread count and tile order. A time
/// limit stops between passes, so its images are those of some N.

#include <cstdint>
#include <filesystem>

#include "btf/core/image.h"
#include "btf/render/integrator.h"
#include "btf/render/scene.h"
#include "btf/util/progress.h"

namespace btf::render {

struct RenderOptions {
    int spp = 16;           ///< samples per pixel (0 = until the time limit)
    double time_limit = 0;  ///< seconds (0 = none)
    uint64_t seed = 1;
    bool aovs = false;  ///< also record albedo, normal and uv at the first hit
    IntegratorOptions integrator;
};

struct RenderResult {
    Image color;  ///< linear radiance, the mean of `spp` samples per pixel, clamped at ≥ 0
    Image albedo, normal, uv;  ///< AOVs (when requested): first-hit albedo, world normal, uv
    int spp = 0;
    double seconds = 0;
    /// Samples left out of their pixel's mean because they were not finite (counted in the
    /// divisor, so such pixels are slightly dark): non-zero means a numerical problem.
    uint64_t dropped = 0;
    uint64_t paths() const { return uint64_t(color.num_pixels()) * uint64_t(spp); }
};

RenderResult render(const Scene& scene, const RenderOptions& options,
                    Progress& progress = Progress::none());

/// Writes `result` for an output path: a float format (`.exr`, is_float_image_format()) holds
/// linear radiance; `.png` (or any 8-bit format) is tone-mapped (quality::tone_map); with AOVs,
/// `<stem>.albedo.exr`, `<stem>.normal.exr` and `<stem>.uv.exr` beside it. All files appear
/// together or, on failure, none.
/// Throws btf::Error unless write_render() can write `path` (and the AOVs): called before a long
/// render starts.
void check_render_output(const std::filesystem::path& path, bool aovs);
void write_render(const std::filesystem::path& path, const RenderResult& result,
                  double exposure = 0);

}  // namespace btf::render
