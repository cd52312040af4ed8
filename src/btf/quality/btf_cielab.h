// SPDX-License-Identifier: MIT
#pragma once
/// BTF-CIELab (Guthe, Müller, Schneider, Klein 2009): the perceptual difference of two BTFs of
/// equal extent and sampling under a range of viewing conditions. Both BTFs are converted to cone
/// responses and lαβ opponent channels, filtered by a spatio-angular contrast sensitivity function
/// (sums of 6-D Gaussians, Table 1: three achromatic, two chromatic), converted to CIELab and
/// compared texel by texel with CIEDE2000.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "btf/util/progress.h"

namespace btf {
class BtfSource;
}

namespace btf::quality {

/// How the BTF is seen: how fast light or view move across it (angular speed, degrees of
/// direction per second) and how many texels one degree of visual angle covers.
struct ViewingCondition {
    double angular_speed = 100;  ///< ω_ang, °/s, in [10, 1000]
    double resolution = 10;      ///< r_s, texels per degree, in [2, 100]
};

struct BtfCielabOptions {
    /// The conditions to evaluate; empty means a log-uniform grid of `grid` × `grid` over
    /// [10, 1000] °/s × [2, 100] px/deg.
    std::vector<ViewingCondition> conditions;
    int grid = 5;
    /// Search the condition of maximum RMS difference (from the grid's worst point) instead of
    /// stopping at the grid.
    bool search = false;
    /// Memory for the filtered channels of both BTFs; above it they are spilled to a file in
    /// `scratch` (default: the system temporary folder), which is removed afterwards.
    int64_t memory_bytes = int64_t(4) << 30;
    std::filesystem::path scratch;
    /// Bits per stored channel value (8 as in the paper's §4.4, or 16).
    int bits = 16;
};

/// The difference at one viewing condition: statistics of the per-sample CIEDE2000 of the
/// perceived BTFs, each texel weighted by cos θ of its view (its projected area).
struct BtfCielabValue {
    ViewingCondition condition;
    double mean = 0, stddev = 0, rms = 0;
};

struct BtfCielabResult {
    std::vector<BtfCielabValue> values;  ///< one per evaluated condition
    int worst = 0;                       ///< index of the largest rms: the reported number
    bool searched = false;               ///< whether `worst` came from the search
    int64_t store_bytes = 0;             ///< size of the filtered-channel store
    bool spilled = false;                ///< whether it went to disk
    double seconds = 0;
    const BtfCielabValue& headline() const { return values[size_t(worst)]; }
};

/// Throws btf::Error naming both sources on mismatched extent or sampling.
BtfCielabResult btf_cielab(const BtfSource& reference, const BtfSource& test,
                           const BtfCielabOptions& options = {},
                           Progress& progress = Progress::none());

}  // namespace btf::quality
