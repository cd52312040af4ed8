// SPDX-License-Identifier: MIT
#pragma once
/// What `btf quality` measures, as one library call: the metrics of compare() and, on request,
/// BTF-CIELab, and their JSON form (what `btf quality --json` prints and the Python module's
/// quality() returns).

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

#include "btf/io/source.h"
#include "btf/quality/btf_cielab.h"
#include "btf/quality/metrics.h"
#include "btf/util/progress.h"

namespace btf::quality {

/// The names a metric list takes.
constexpr const char* kMetricNames = "rmse, lab, de2000, ssim, btf-cielab";

struct QualityRequest {
    CompareOptions compare;  ///< compare.metrics: which of rmse, lab, de2000, ssim
    bool btf_cielab = false;
    BtfCielabOptions cielab;

    /// From a comma-separated list of kMetricNames; throws btf::Error "unknown metric 'x'; the
    /// metrics are …" otherwise. The other options keep their defaults.
    static QualityRequest parse(const std::string& list);
};

struct QualityResult {
    MetricSelection selection;
    std::optional<Metrics> metrics;             ///< when any of compare()'s metrics was asked
    std::optional<BtfCielabResult> perceptual;  ///< when btf-cielab was asked
    int width = 0, height = 0, views = 0, lights = 0;
};

/// Checks that the two are comparable (check_comparable()), then measures what `request` asks.
QualityResult measure(const BtfSource& reference, const BtfSource& test,
                      const QualityRequest& request, Progress& progress = Progress::none());

/// The result as `btf quality --json` prints it, without the inputs' names: extent, then
/// rmse/psnr, lab_mae, de2000, ssim and btf_cielab for what was measured (an infinite PSNR,
/// of identical inputs, as null).
nlohmann::json to_json(const QualityResult& result);

}  // namespace btf::quality
