// SPDX-License-Identifier: MIT
// The report's page (index.html), its numbers (report.json) and its rate–distortion plots, made
// from a Report whose image files exist. Nothing here measures anything.

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "btf/quality/plot.h"
#include "btf/quality/report.h"

namespace btf::quality {

namespace {

std::string esc(std::string_view text) {
    return xml_escape(text);
}

std::string bytes_text(double bytes) {
    const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
    int u = 0;
    while (bytes >= 1024 && u < 4) bytes /= 1024, ++u;
    return u == 0 ? fmt::format("{:.0f} B", bytes) : fmt::format("{:.1f} {}", bytes, units[u]);
}

std::string seconds_text(double s) {
    if (s < 10) return fmt::format("{:.2f} s", s);
    if (s < 120) return fmt::format("{:.1f} s", s);
    const int whole = int(std::lround(s));
    return fmt::format("{} min {:02} s", whole / 60, whole % 60);
}

std::string ratio_text(double ratio) {
    return ratio >= 10 ? fmt::format("{:.0f}:1", ratio) : fmt::format("{:.1f}:1", ratio);
}

std::string degrees_text(double deg) {
    std::string text = fmt::format("{:.1f}", deg);
    if (text.size() > 2 && text.compare(text.size() - 2, 2, ".0") == 0)
        text.resize(text.size() - 2);
    if (text == "-0") text = "0";
    return text + "\u00b0";
}

std::string psnr_text(double psnr) {
    return std::isfinite(psnr) ? fmt::format("{:.2f}", psnr) : "\u221e";
}

double ycrcb_mean(const Metrics& m) {
    return (m.ssim_ycrcb[0] + m.ssim_ycrcb[1] + m.ssim_ycrcb[2]) / 3;
}

std::string condition_text(const ViewingCondition& c) {
    return fmt::format("{:.3g}\u00b0/s, {:.3g} px/\u00b0", c.angular_speed, c.resolution);
}

std::string direction_text(const char* what, const Direction& d) {
    return fmt::format("{} \u03b8 {}, \u03c6 {}", what, degrees_text(d.theta_deg()),
                       degrees_text(d.phi_deg()));
}

constexpr int kPlotWidth = 600, kPlotHeight = 380;

// The factor a picture `width` pixels wide is shown at: a small one is enlarged by a whole factor
// to at least `at_least` pixels, a large one reduced to at most `at_most`.
double display_scale(int width, int at_least, int at_most) {
    if (width < at_least) return double((at_least + width - 1) / width);
    if (width > at_most) return double(at_most) / width;
    return 1;
}

constexpr const char* kStyle = R"(
body { font-family: system-ui, "Segoe UI", Helvetica, Arial, sans-serif; color: #1d1d1f;
       margin: 24px auto; max-width: 1240px; padding: 0 16px; line-height: 1.45; }
h1 { font-size: 24px; margin-bottom: 4px; }
h2 { font-size: 19px; margin-top: 36px; border-bottom: 1px solid #ccc; padding-bottom: 4px; }
h3 { font-size: 16px; margin: 24px 0 6px; }
dl.facts { display: grid; grid-template-columns: max-content auto; gap: 2px 16px; }
dl.facts dt { font-weight: bold; } dl.facts dd { margin: 0; }
table.results { border-collapse: collapse; font-variant-numeric: tabular-nums; font-size: 14px; }
table.results th, table.results td { padding: 4px 9px; border-bottom: 1px solid #ddd;
       text-align: right; vertical-align: top; }
table.results th { background: #f3f3f5; border-bottom: 2px solid #bbb; }
table.results .text { text-align: left; }
table.results th, table.results td:not(.params) { white-space: nowrap; }
table.results td.best { font-weight: bold; background: #eaf4ea; }
.cond { display: block; font-size: 12px; color: #555; }
p.caption, figcaption { font-size: 13px; color: #444; max-width: 1000px; }
div.plots { display: flex; flex-wrap: wrap; gap: 16px; }
img.pixels { image-rendering: pixelated; image-rendering: crisp-edges; }
table.images { border-collapse: collapse; }
table.images td, table.images th { padding: 4px 10px 4px 0; vertical-align: middle;
       text-align: left; font-size: 13px; }
div.image-section { display: flex; gap: 16px; align-items: flex-start; }
table.images td.config { width: 170px; }
table.images td.config span { display: block; color: #555; }
footer { margin-top: 40px; padding-top: 8px; border-top: 1px solid #ccc; font-size: 12px;
       color: #555; }
code { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 12px;
       word-break: break-all; }
)";

// Marks the best configuration per column (ties all marked); nothing with a single row.
std::vector<bool> best_of(const std::vector<double>& values, bool higher_is_better) {
    std::vector<bool> best(values.size(), false);
    if (values.size() < 2) return best;
    double target = higher_is_better ? -INFINITY : INFINITY;
    for (const double v : values)
        if (!std::isnan(v)) target = higher_is_better ? std::max(target, v) : std::min(target, v);
    for (size_t i = 0; i < values.size(); ++i) best[i] = values[i] == target;
    return best;
}

}  // namespace

std::string rate_distortion_svg(const Report& report, RdMeasure measure) {
    std::vector<PlotSeries> series;
    for (const ConfigResult& c : report.configs) {
        double y = 0;
        if (measure == RdMeasure::kPsnr) {
            y = c.metrics.psnr;
        } else if (measure == RdMeasure::kDe2000) {
            y = c.metrics.de2000_mean;
        } else {
            if (!c.cielab) continue;
            y = c.cielab->headline().mean;
        }
        // One line per codec and factor storage: "fmf", "fmf (coded)".
        std::string name = c.config.codec;
        for (const auto& [key, value] : c.config.params)
            if (key == "quantize") name += " (" + value + ")";
        auto it = std::find_if(series.begin(), series.end(),
                               [&](const PlotSeries& s) { return s.name == name; });
        if (it == series.end()) {
            series.push_back({name, {}});
            it = series.end() - 1;
        }
        it->points.push_back({c.bits_per_sample, y, c.config.parameters_text()});
    }
    PlotOptions options;
    options.width = kPlotWidth;
    options.height = kPlotHeight;
    options.x = {"bits per texel per (view, light) pair", true};
    if (measure == RdMeasure::kPsnr) {
        options.title = "PSNR against rate (higher is better)";
        options.y = {"PSNR, linear RGB (dB)", false};
    } else if (measure == RdMeasure::kDe2000) {
        options.title = "Mean CIEDE2000 against rate (lower is better)";
        options.y = {"mean \u0394E00 over every sample", false};
    } else {
        options.title = "BTF-CIELab against rate (lower is better)";
        options.y = {"BTF-CIELab mean \u0394E00, worst condition", false};
    }
    return svg_line_plot(options, series);
}

nlohmann::json report_json(const Report& report) {
    using nlohmann::json;
    const ReferenceFacts& r = report.reference;
    json out;
    out["generator"] = "btfkit report";
    out["version"] = report.generator;
    out["created"] = report.created;
    if (!report.render_reference.empty())
        out["render"] = {{"reference", report.render_reference},
                         {"caption", report.render_caption},
                         {"heat_map_max", report.render_heat_max}};
    out["command"] = report.command_line;
    out["seconds"] = report.seconds;
    out["reference"] = {
        {"name", r.name},           {"format", r.format}, {"path", r.path},
        {"note", r.note},           {"width", r.width},   {"height", r.height},
        {"views", r.views},         {"lights", r.lights}, {"view_set", r.view_set},
        {"light_set", r.light_set}, {"hdr", r.hdr},       {"raw_8bit_bytes", r.raw_8bit_bytes}};
    out["images"] = json::array();
    for (size_t k = 0; k < report.images.size(); ++k) {
        const ReportImage& image = report.images[k];
        out["images"].push_back(
            {{"view", image.view},
             {"light", image.light},
             {"label", image.label},
             {"view_theta", image.view_direction.theta_deg()},
             {"view_phi", image.view_direction.phi_deg()},
             {"light_theta", image.light_direction.theta_deg()},
             {"light_phi", image.light_direction.phi_deg()},
             {"heat_map_max_de2000", k < report.heat_max.size() ? report.heat_max[k] : 0.0}});
    }
    out["crop"] = {{"x", report.crop_x},
                   {"y", report.crop_y},
                   {"width", report.crop_width},
                   {"height", report.crop_height},
                   {"difference_gain", report.difference_gain},
                   {"exposure", report.exposure}};
    out["btf_cielab"] = report.btf_cielab;
    out["configs"] = json::array();
    for (const ConfigResult& c : report.configs) {
        const Metrics& m = c.metrics;
        json params = json::object();
        for (const auto& [key, value] : c.config.params) params[key] = value;
        json item = {{"id", c.id},
                     {"codec", c.config.codec},
                     {"params", params},
                     {"package", c.package.empty() ? json(nullptr) : json(c.package)},
                     {"bytes", c.bytes},
                     {"ratio", c.ratio},
                     {"bits_per_sample", c.bits_per_sample},
                     {"encode_seconds", c.encode_seconds},
                     {"rmse", m.rmse},
                     {"psnr", std::isfinite(m.psnr) ? json(m.psnr) : json(nullptr)},
                     {"peak", m.peak},
                     {"lab_mae", m.lab_mae},
                     {"de2000_mean", m.de2000_mean},
                     {"de2000_p95", m.de2000_p95},
                     {"de2000_max", m.de2000_max},
                     {"mssim_y", m.ssim_luminance},
                     {"mssim_ycrcb", m.ssim_ycrcb},
                     {"metrics_seconds", m.seconds}};
        if (c.cielab) {
            json values = json::array();
            for (const BtfCielabValue& v : c.cielab->values)
                values.push_back({{"angular_speed", v.condition.angular_speed},
                                  {"resolution", v.condition.resolution},
                                  {"mean", v.mean},
                                  {"stddev", v.stddev},
                                  {"rms", v.rms}});
            const BtfCielabValue& worst = c.cielab->headline();
            item["btf_cielab"] = {{"mean", worst.mean},
                                  {"rms", worst.rms},
                                  {"angular_speed", worst.condition.angular_speed},
                                  {"resolution", worst.condition.resolution},
                                  {"searched", c.cielab->searched},
                                  {"seconds", c.cielab->seconds},
                                  {"conditions", values}};
        }
        if (c.render)
            item["render"] = {
                {"image", c.render->image},
                {"heat_map", c.render->heat_map},
                {"de2000_mean", c.render->de2000_mean},
                {"de2000_p95", c.render->de2000_p95},
                {"ssim", c.render->ssim},
                {"psnr", std::isfinite(c.render->psnr) ? json(c.render->psnr) : json(nullptr)}};
        item["images"] = json::array();
        for (const ConfigImage& image : c.images)
            item["images"].push_back({{"crops", image.crops},
                                      {"heat_map", image.heat_map},
                                      {"de2000_mean", image.de2000_mean},
                                      {"de2000_max", image.de2000_max}});
        out["configs"].push_back(std::move(item));
    }
    return out;
}

std::string report_html(const Report& report) {
    const ReferenceFacts& ref = report.reference;
    std::string h;
    h += "<!DOCTYPE html>\n<html xmlns=\"http://www.w3.org/1999/xhtml\" lang=\"en\">\n<head>\n";
    h += "<meta charset=\"utf-8\"/>\n";
    h += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n";
    h += fmt::format("<title>Compression report: {}</title>\n", esc(ref.name));
    h += fmt::format("<style>{}</style>\n</head>\n<body>\n", kStyle);

    // ---- the reference
    h += fmt::format("<h1>Compression report: {}</h1>\n", esc(ref.name));
    h += fmt::format(
        "<p class=\"caption\">{} codec configuration{} compared with the reference below, sample "
        "by sample.</p>\n",
        report.configs.size(), report.configs.size() == 1 ? "" : "s");
    h += "<dl class=\"facts\">\n";
    auto fact = [&](const std::string& term, const std::string& value) {
        h += fmt::format("<dt>{}</dt><dd>{}</dd>\n", esc(term), value);
    };
    fact("Source", ref.path.empty() || ref.path == ref.name
                       ? esc(ref.name)
                       : esc(ref.name) + " (<code>" + esc(ref.path) + "</code>)");
    fact("Format", esc(ref.format) + (ref.hdr ? " (HDR values)" : " (LDR values)"));
    fact("Extent", fmt::format("{} \u00d7 {} texels", ref.width, ref.height));
    fact("Sampling", fmt::format("{} views ({}) \u00d7 {} lights ({}) = {} images", ref.views,
                                 esc(ref.view_set), ref.lights, esc(ref.light_set),
                                 int64_t(ref.views) * ref.lights));
    fact("Raw size", esc(bytes_text(ref.raw_8bit_bytes)) + " as 8-bit RGB");
    if (!ref.note.empty()) fact("Note", esc(ref.note));
    h += "</dl>\n";

    // ---- the table
    h += "<h2 id=\"results-section\">Results</h2>\n<table class=\"results\" "
         "id=\"results\">\n<thead><tr>";
    const char* headers[] = {
        "#",    "codec",     "parameters",     "package", "ratio",       "bits / sample", "encode",
        "RMSE", "PSNR (dB)", "\u0394E00 mean", "MSSIM Y", "MSSIM YCrCb", "BTF-CIELab"};
    for (size_t i = 0; i < std::size(headers); ++i)
        h += fmt::format("<th{}>{}</th>", i == 1 || i == 2 ? " class=\"text\"" : "",
                         esc(headers[i]));
    h += "</tr></thead>\n<tbody>\n";
    auto column = [&](const std::function<double(const ConfigResult&)>& value, bool higher) {
        std::vector<double> values;
        for (const ConfigResult& c : report.configs) values.push_back(value(c));
        return best_of(values, higher);
    };
    const auto best_bytes = column([](const ConfigResult& c) { return double(c.bytes); }, false);
    const auto best_time = column([](const ConfigResult& c) { return c.encode_seconds; }, false);
    const auto best_rmse = column([](const ConfigResult& c) { return c.metrics.rmse; }, false);
    const auto best_de = column([](const ConfigResult& c) { return c.metrics.de2000_mean; }, false);
    const auto best_ssim =
        column([](const ConfigResult& c) { return c.metrics.ssim_luminance; }, true);
    const auto best_ycc = column([](const ConfigResult& c) { return ycrcb_mean(c.metrics); }, true);
    const auto best_cielab = column(
        [](const ConfigResult& c) { return c.cielab ? c.cielab->headline().mean : NAN; }, false);
    for (size_t i = 0; i < report.configs.size(); ++i) {
        const ConfigResult& c = report.configs[i];
        const Metrics& m = c.metrics;
        auto cell = [&](const std::string& content, bool best, const std::string& title = "") {
            std::string attributes = best ? " class=\"best\"" : "";
            if (!title.empty()) attributes += " title=\"" + esc(title) + "\"";
            return fmt::format("<td{}>{}</td>", attributes, content);
        };
        std::string size = esc(bytes_text(double(c.bytes)));
        if (!c.package.empty()) size = fmt::format("<a href=\"{}\">{}</a>", esc(c.package), size);
        h += fmt::format("<tr id=\"{}\">", esc(c.id));
        h += fmt::format("<td>{}</td><td class=\"text\">{}</td><td class=\"text params\">{}</td>",
                         i + 1, esc(c.config.codec), esc(c.config.parameters_text()));
        h += cell(size, best_bytes[i], fmt::format("{} bytes", c.bytes));
        h += cell(esc(ratio_text(c.ratio)), best_bytes[i]);
        h += cell(fmt::format("{:.3g}", c.bits_per_sample), best_bytes[i]);
        h += cell(esc(seconds_text(c.encode_seconds)), best_time[i]);
        h += cell(fmt::format("{:.4g}", m.rmse), best_rmse[i]);
        h += cell(psnr_text(m.psnr), best_rmse[i], fmt::format("peak {:g}", m.peak));
        h += cell(fmt::format("{:.2f}", m.de2000_mean), best_de[i],
                  fmt::format("95th percentile {:.2f}, max {:.2f}", m.de2000_p95, m.de2000_max));
        h += cell(fmt::format("{:.4f}", m.ssim_luminance), best_ssim[i]);
        h += cell(fmt::format("{:.4f}", ycrcb_mean(m)), best_ycc[i],
                  fmt::format("Y {:.4f}, Cr {:.4f}, Cb {:.4f}", m.ssim_ycrcb[0], m.ssim_ycrcb[1],
                              m.ssim_ycrcb[2]));
        if (c.cielab) {
            const BtfCielabValue& w = c.cielab->headline();
            h += cell(fmt::format("{:.2f}<span class=\"cond\">at {}</span>", w.mean,
                                  esc(condition_text(w.condition))),
                      best_cielab[i],
                      fmt::format("rms {:.2f}, stddev {:.2f} at the worst of {} conditions{}",
                                  w.rms, w.stddev, c.cielab->values.size(),
                                  c.cielab->searched ? " (searched)" : ""));
        } else {
            h += "<td>\u2013</td>";
        }
        h += "</tr>\n";
    }
    h += "</tbody>\n</table>\n";
    h += fmt::format(
        "<p class=\"caption\">As Table 2 of Havran et al. (2010), one row per configuration. "
        "<b>ratio</b>: raw 8-bit RGB size / package size; <b>bits / sample</b>: 8 \u00b7 package "
        "bytes / (texels \u00b7 images), the bits per texel per (view, light) pair; "
        "<b>encode</b>: wall-clock time of the encoder; <b>RMSE</b> and <b>PSNR</b>: linear RGB "
        "over every texel, image and channel; <b>\u0394E00</b>: CIEDE2000 per sample, mean; "
        "<b>MSSIM</b>: mean over images of the structural similarity of luminance Y, and the "
        "mean of the Y, Cr and Cb channels' (1 = identical); <b>BTF-CIELab</b>: Guthe et al. "
        "(2009), the mean perceived \u0394E00 at the viewing condition (angular speed, texels per "
        "degree) where the difference is largest, {}. Bold: the best value of a column. Hover a "
        "cell for details.</p>\n",
        report.btf_cielab
            ? report.cielab_options.conditions.empty()
                  ? fmt::format("of a {0} \u00d7 {0} grid of conditions",
                                report.cielab_options.grid)
                  : fmt::format("of {} given conditions", report.cielab_options.conditions.size())
            : "not computed for this report");

    // ---- rate–distortion
    h += "<h2 id=\"rate-distortion\">Rate and distortion</h2>\n<div class=\"plots\">\n";
    h += fmt::format(
        "<img src=\"rd-psnr.svg\" width=\"{}\" height=\"{}\" alt=\"PSNR against bits per "
        "sample\"/>\n",
        kPlotWidth, kPlotHeight);
    h += fmt::format(
        "<img src=\"rd-de2000.svg\" width=\"{}\" height=\"{}\" alt=\"mean CIEDE2000 against "
        "bits per sample\"/>\n",
        kPlotWidth, kPlotHeight);
    if (report.btf_cielab)
        h += fmt::format(
            "<img src=\"rd-btf-cielab.svg\" width=\"{}\" height=\"{}\" alt=\"BTF-CIELab "
            "against bits per sample\"/>\n",
            kPlotWidth, kPlotHeight);
    h += "</div>\n<p class=\"caption\">One series per codec, its configurations joined in order "
         "of rate (logarithmic axis). Hover a marker for its parameters. A lossless result "
         "(infinite PSNR) is not drawn.</p>\n";

    // ---- images
    h += "<h2 id=\"error-images\">Error images</h2>\n";
    h += fmt::format(
        "<p class=\"caption\">Each selected (view, light) image: a {}\u00d7{} texel crop at "
        "({}, {}) of the reference, the decoded image and their difference amplified "
        "\u00d7{:g} (of the displayed sRGB values){}; beside it the CIEDE2000 difference of "
        "every texel of the whole image on a perceptual colour map (dark blue: no difference; its "
        "top, stated by the colour bar, is the 99th percentile of that image's errors over "
        "every configuration, rounded up; larger values take the top colour). Small pictures are "
        "enlarged without smoothing.</p>\n",
        report.crop_width, report.crop_height, report.crop_x, report.crop_y, report.difference_gain,
        report.exposure != 1 ? fmt::format(", exposure \u00d7{:.3g} for display", report.exposure)
                             : "");
    // Crops enlarged to show texels; heat maps at a size that fits beside them.
    const int crops_width = 3 * report.crop_width + 2 * kCropGap;
    const double crop_scale = display_scale(report.crop_width, 192, 4096);
    const double heat_scale = display_scale(std::max(ref.width, ref.height), 192, 256);
    for (size_t i = 0; i < report.images.size(); ++i) {
        const ReportImage& image = report.images[i];
        h += fmt::format("<h3>{}</h3>\n", esc(image.label));
        h += fmt::format("<p class=\"caption\">{} (index {}), {} (index {})</p>\n",
                         esc(direction_text("view", image.view_direction)), image.view,
                         esc(direction_text("light", image.light_direction)), image.light);
        h += "<div class=\"image-section\">\n<table class=\"images\">\n";
        h += fmt::format(
            "<tr><th>configuration</th><th>reference | decoded | difference \u00d7{:g}</th>"
            "<th>\u0394E00 per texel</th></tr>\n",
            report.difference_gain);
        for (const ConfigResult& c : report.configs) {
            const ConfigImage& ci = c.images[i];
            h += fmt::format(
                "<tr><td class=\"config\"><b>{}</b><span>{}</span><span>\u0394E00 mean {:.2f}, "
                "max {:.2f}</span></td>",
                esc(c.config.codec), esc(c.config.parameters_text()), ci.de2000_mean,
                ci.de2000_max);
            h += fmt::format(
                "<td><img class=\"pixels\" src=\"{}\" width=\"{}\" height=\"{}\" alt=\"crops "
                "{}\"/></td>",
                esc(ci.crops), std::lround(crops_width * crop_scale),
                std::lround(report.crop_height * crop_scale), esc(c.config.label()));
            h += fmt::format(
                "<td><img class=\"pixels\" src=\"{}\" width=\"{}\" height=\"{}\" alt=\"heat map "
                "{}\"/></td></tr>\n",
                esc(ci.heat_map), std::lround(ref.width * heat_scale),
                std::lround(ref.height * heat_scale), esc(c.config.label()));
        }
        h += fmt::format(
            "</table>\n<img src=\"colorbar-{}.svg\" width=\"110\" height=\"320\" alt=\"colour "
            "scale\"/>\n</div>\n",
            i + 1);
    }

    // ---- renders
    if (!report.render_reference.empty()) {
        h += "<h2 id=\"renders\">Rendered</h2>\n";
        h += fmt::format(
            "<p class=\"caption\">{}. The reference (the uncompressed material) and every "
            "configuration's package rendered with the same scene, camera and random seed; beside "
            "each render the CIEDE2000 difference to the reference's render per pixel, on the "
            "displayed (tone-mapped) values, from 0 (dark blue) to {:g}. Monte Carlo noise that "
            "differs between two renders shows as speckle, a material difference as "
            "structure.</p>\n",
            esc(report.render_caption), report.render_heat_max);
        h += "<div class=\"image-section\">\n<table class=\"images\">\n";
        h += fmt::format(
            "<tr><td class=\"config\"><b>reference</b></td><td><img src=\"{}\" "
            "alt=\"reference render\"/></td><td></td></tr>\n",
            esc(report.render_reference));
        for (const ConfigResult& c : report.configs) {
            if (!c.render) continue;
            h += fmt::format(
                "<tr><td class=\"config\"><b>{}</b><span>{}</span><span>\u0394E00 mean {:.2f}, "
                "95th percentile {:.2f}</span><span>SSIM {:.4f}, PSNR {} dB</span></td>",
                esc(c.config.codec), esc(c.config.parameters_text()), c.render->de2000_mean,
                c.render->de2000_p95, c.render->ssim, esc(psnr_text(c.render->psnr)));
            h += fmt::format(
                "<td><img src=\"{}\" alt=\"render {}\"/></td><td><img src=\"{}\" alt=\"render "
                "difference {}\"/></td></tr>\n",
                esc(c.render->image), esc(c.config.label()), esc(c.render->heat_map),
                esc(c.config.label()));
        }
        h += "</table>\n<img src=\"colorbar-render.svg\" width=\"110\" height=\"320\" "
             "alt=\"colour scale\"/>\n</div>\n";
    }

    // ---- footer
    h += "<footer>\n";
    h += fmt::format("<p>Written by {} on {} in {}.</p>\n", esc(report.generator),
                     esc(report.created), esc(seconds_text(report.seconds)));
    if (!report.command_line.empty())
        h += fmt::format("<p>Command: <code>{}</code></p>\n", esc(report.command_line));
    h += "<p>Every number of this page is in <a href=\"report.json\">report.json</a>.</p>\n";
    h += "</footer>\n</body>\n</html>\n";
    return h;
}

}  // namespace btf::quality
