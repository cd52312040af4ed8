// SPDX-License-Identifier: MIT
#include "btf/quality/measure.h"

#include <cmath>
#include <vector>

#include "btf/util/error.h"

namespace btf::quality {

namespace {

// +inf (identical inputs) has no JSON number: null.
nlohmann::json json_number(double v) {
    return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace

QualityRequest QualityRequest::parse(const std::string& list) {
    QualityRequest request;
    std::vector<std::string> rest;
    request.compare.metrics = MetricSelection::parse(list, &rest);
    for (const std::string& name : rest) {
        if (name != "btf-cielab")
            fail("unknown metric '{}'; the metrics are {}", name, kMetricNames);
        request.btf_cielab = true;
    }
    return request;
}

QualityResult measure(const BtfSource& reference, const BtfSource& test,
                      const QualityRequest& request, Progress& progress) {
    check_comparable(reference, test);
    QualityResult out;
    out.selection = request.compare.metrics;
    if (out.selection.any()) out.metrics = compare(reference, test, request.compare, progress);
    if (request.btf_cielab) out.perceptual = btf_cielab(reference, test, request.cielab, progress);
    out.width = reference.width(), out.height = reference.height();
    out.views = reference.num_views(), out.lights = reference.num_lights();
    return out;
}

nlohmann::json to_json(const QualityResult& result) {
    nlohmann::json j;
    j["width"] = result.width;
    j["height"] = result.height;
    j["views"] = result.views;
    j["lights"] = result.lights;
    j["images"] = int64_t(result.views) * result.lights;
    if (result.metrics) {
        const Metrics& m = *result.metrics;
        const MetricSelection& selection = result.selection;
        j["peak"] = m.peak;
        j["cos_weighted"] = m.cos_weighted;
        j["seconds"] = m.seconds;
        if (selection.rmse) {
            j["rmse"] = m.rmse;
            j["psnr"] = json_number(m.psnr);
        }
        if (selection.lab)
            j["lab_mae"] = {{"L", m.lab_mae[0]}, {"a", m.lab_mae[1]}, {"b", m.lab_mae[2]}};
        if (selection.de2000)
            j["de2000"] = {{"mean", m.de2000_mean},
                           {"p95", m.de2000_p95},
                           {"max", m.de2000_max},
                           {"p95_bin_width", kDe2000BinWidth}};
        if (selection.ssim)
            j["ssim"] = {{"luminance", m.ssim_luminance},
                         {"Y", m.ssim_ycrcb[0]},
                         {"Cr", m.ssim_ycrcb[1]},
                         {"Cb", m.ssim_ycrcb[2]}};
    }
    if (result.perceptual) {
        const BtfCielabResult& p = *result.perceptual;
        const BtfCielabValue& h = p.headline();
        nlohmann::json conditions = nlohmann::json::array();
        for (const BtfCielabValue& v : p.values)
            conditions.push_back({{"angular_speed", v.condition.angular_speed},
                                  {"resolution", v.condition.resolution},
                                  {"mean", v.mean},
                                  {"stddev", v.stddev},
                                  {"rms", v.rms}});
        j["btf_cielab"] = {{"mean", h.mean},
                           {"stddev", h.stddev},
                           {"rms", h.rms},
                           {"angular_speed", h.condition.angular_speed},
                           {"resolution", h.condition.resolution},
                           {"searched", p.searched},
                           {"conditions", conditions},
                           {"seconds", p.seconds}};
    }
    return j;
}

}  // namespace btf::quality
