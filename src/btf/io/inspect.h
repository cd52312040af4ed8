// SPDX-License-Identifier: MIT
#pragma once
/// What `btf info` shows about a source: sizes and value statistics.

#include <array>
#include <cstdint>
#include <filesystem>

#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf {

struct ValueStats {
    int64_t images = 0;      ///< images read
    int64_t values = 0;      ///< finite values counted (per channel)
    int64_t non_finite = 0;  ///< NaN or Inf values seen
    std::array<double, 3> min{}, max{}, mean{};
    double mean_luminance = 0;
};

/// Statistics over `max_images` images spread evenly over all (view, light) pairs (all images
/// when max_images <= 0 or >= the number of images). Reads images in parallel.
ValueStats value_stats(const BtfSource& source, int64_t max_images,
                       Progress& progress = Progress::none());

/// Bytes on disk of a file, or of all regular files under a folder.
uint64_t disk_usage(const std::filesystem::path& path);

}  // namespace btf
