// SPDX-License-Identifier: MIT
// btf quality REF TEST [--metrics rmse,lab,de2000,ssim,btf-cielab] [--json] [--cos-weight]
// [--peak X] [--grid N] [--search]: how far TEST is from REF (two BTFs of equal extent and
// sampling, or a BTF and a package decoded through its codec).

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <optional>

#include "btf/quality/btf_cielab.h"
#include "btf/quality/measure.h"
#include "btf/quality/metrics.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

std::string number(double v) {
    return fmt::format("{:.6g}", v);
}

std::string condition_text(const quality::ViewingCondition& c) {
    return fmt::format("ω = {:.4g} °/s, r_s = {:.4g} px/deg", c.angular_speed, c.resolution);
}

}  // namespace

Command register_quality(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string reference, test, metrics = "rmse,lab,de2000,ssim";
        bool json = false, cos_weight = false, search = false;
        double peak = 0;
        int grid = quality::BtfCielabOptions{}.grid;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "quality",
        "Measure how far TEST is from REF: RMSE and PSNR (linear RGB), CIELab MAE, CIEDE2000, "
        "SSIM, and the perceptual BTF-CIELab (docs/quality.md defines each)");
    cmd->add_option("reference", args->reference,
                    "reference BTF file or folder (any format btfkit reads), or a btfkit package")
        ->required();
    cmd->add_option("test", args->test,
                    "BTF or package to measure, of the same extent and sampling")
        ->required();
    cmd->add_option("--metrics", args->metrics,
                    fmt::format("comma-separated measures, from: {}", quality::kMetricNames));
    cmd->add_flag("--json", args->json, "print JSON instead of a table");
    auto* cos_weight = cmd->add_flag(
        "--cos-weight", args->cos_weight,
        "weight every image by cos θ of its view in the means and the 95th percentile");
    auto* peak = cmd->add_option("--peak", args->peak,
                                 "peak value for PSNR and SSIM (default: 1 for LDR references, "
                                 "the largest reference value for HDR ones)")
                     ->check(CLI::PositiveNumber);
    auto* grid = cmd->add_option("--grid", args->grid,
                                 "btf-cielab: viewing conditions per axis of the log-uniform grid")
                     ->check(CLI::Range(1, 64));
    auto* search = cmd->add_flag("--search", args->search,
                                 "btf-cielab: search the viewing condition of the largest "
                                 "difference from the grid's worst point");

    return {cmd, [args, &global, cos_weight, peak, grid, search] {
                // Arguments first: opening and comparing large BTFs takes long.
                quality::QualityRequest request;
                try {
                    request = quality::QualityRequest::parse(args->metrics);
                } catch (const Error& e) {
                    fail("--metrics: {}", e.what());
                }
                const quality::MetricSelection& selection = request.compare.metrics;
                if ((grid->count() || search->count()) && !request.btf_cielab)
                    fail("--grid and --search apply to btf-cielab: add it to --metrics");
                if ((cos_weight->count() || peak->count()) && !selection.any())
                    fail(
                        "--cos-weight and --peak apply to rmse, lab, de2000 and ssim, which "
                        "--metrics does not name");
                request.compare.cos_weight = args->cos_weight;
                request.compare.peak = args->peak;
                request.cielab.grid = args->grid;
                request.cielab.search = args->search;

                const auto reference = open_input(args->reference, {}, "");
                const auto test = open_input(args->test, {}, "");
                Progress progress = make_progress(global);
                const quality::QualityResult result =
                    quality::measure(*reference, *test, request, progress);
                const std::optional<quality::Metrics>& metrics = result.metrics;
                const std::optional<quality::BtfCielabResult>& perceptual = result.perceptual;

                const Sampling& s = reference->sampling();
                if (args->json) {
                    nlohmann::json j = quality::to_json(result);
                    j["reference"] = args->reference;
                    j["test"] = args->test;
                    std::printf("%s\n", j.dump(2).c_str());
                    return;
                }

                std::vector<std::pair<std::string, std::string>> rows;
                if (metrics) {
                    const quality::Metrics& m = *metrics;
                    if (selection.rmse) {
                        rows.push_back({"RMSE", number(m.rmse) + " (linear RGB)"});
                        rows.push_back(
                            {"PSNR", (std::isfinite(m.psnr) ? fmt::format("{:.2f} dB", m.psnr)
                                                            : std::string("inf dB")) +
                                         fmt::format(" (peak {})", number(m.peak))});
                    }
                    if (selection.lab) {
                        rows.push_back({"MAE L*", number(m.lab_mae[0])});
                        rows.push_back({"MAE a*", number(m.lab_mae[1])});
                        rows.push_back({"MAE b*", number(m.lab_mae[2])});
                    }
                    if (selection.de2000) {
                        rows.push_back({"dE2000 mean", number(m.de2000_mean)});
                        rows.push_back({"dE2000 p95", number(m.de2000_p95)});
                        rows.push_back({"dE2000 max", number(m.de2000_max)});
                    }
                    if (selection.ssim) {
                        rows.push_back({"MSSIM luminance", number(m.ssim_luminance)});
                        rows.push_back({"MSSIM Y", number(m.ssim_ycrcb[0])});
                        rows.push_back({"MSSIM Cr", number(m.ssim_ycrcb[1])});
                        rows.push_back({"MSSIM Cb", number(m.ssim_ycrcb[2])});
                    }
                }
                if (perceptual) {
                    const quality::BtfCielabValue& h = perceptual->headline();
                    rows.push_back({"BTF-CIELab mean", number(h.mean)});
                    rows.push_back({"BTF-CIELab stddev", number(h.stddev)});
                    rows.push_back({"BTF-CIELab rms", number(h.rms)});
                    rows.push_back(
                        {"BTF-CIELab at", condition_text(h.condition) +
                                              (perceptual->searched ? " (searched)" : " (grid)")});
                }
                std::string weighting;
                if (metrics)
                    weighting = metrics->cos_weighted ? ", weighted by cos θ_view" : ", unweighted";
                std::printf("%s vs %s: %d x %d texels, %d views x %d lights%s\n",
                            args->reference.c_str(), args->test.c_str(), reference->width(),
                            reference->height(), s.num_views(), s.num_lights(), weighting.c_str());
                size_t width = 6;
                for (const auto& row : rows) width = std::max(width, row.first.size());
                std::printf("%-*s  %s\n", int(width), "metric", "value");
                for (const auto& [name, value] : rows)
                    std::printf("%-*s  %s\n", int(width), name.c_str(), value.c_str());
            }};
}

}  // namespace btf::cli
