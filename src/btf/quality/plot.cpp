// SPDX-License-Identifier: MIT
#include "btf/quality/plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace btf::quality {

std::string xml_escape(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (const char c : text) {
        switch (c) {
            case '&':
                out += "&amp;";
                break;
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '"':
                out += "&quot;";
                break;
            case '\'':
                out += "&#39;";
                break;
            default:
                out += c;
        }
    }
    return out;
}

namespace {

// The 1-2-5 number nearest `raw` (> 0).
double nice_step(double raw) {
    const double exponent = std::floor(std::log10(raw));
    const double power = std::pow(10.0, exponent);
    const double fraction = raw / power;
    const double nice = fraction < 1.5 ? 1 : fraction < 3 ? 2 : fraction < 7 ? 5 : 10;
    return nice * power;
}

}  // namespace

AxisTicks linear_axis(double lo, double hi, int target) {
    if (!std::isfinite(lo) || !std::isfinite(hi)) lo = 0, hi = 1;
    if (lo > hi) std::swap(lo, hi);
    const double scale = std::max({1.0, std::abs(lo), std::abs(hi)});
    if (hi - lo <= 1e-12 * scale) {
        const double pad = lo == 0 ? 1.0 : 0.1 * std::abs(lo);
        lo -= pad;
        hi += pad;
    }
    const double step = nice_step((hi - lo) / std::max(1, target));
    AxisTicks axis;
    axis.min = std::floor(lo / step + 1e-9) * step;
    axis.max = std::ceil(hi / step - 1e-9) * step;
    const int count = int(std::lround((axis.max - axis.min) / step));
    for (int i = 0; i <= count; ++i) {
        double value = std::round(axis.min / step + i) * step;
        if (std::abs(value) < step * 1e-9) value = 0;
        axis.ticks.push_back(value);
    }
    return axis;
}

AxisTicks log_axis(double lo, double hi) {
    if (!(lo > 0) || !(hi > 0) || !std::isfinite(lo) || !std::isfinite(hi)) lo = 0.1, hi = 1;
    if (lo > hi) std::swap(lo, hi);
    const int e_lo = int(std::floor(std::log10(lo) + 1e-9));
    int e_hi = int(std::ceil(std::log10(hi) - 1e-9));
    if (e_hi == e_lo) ++e_hi;
    AxisTicks axis;
    if (e_hi - e_lo > 2) {
        axis.min = std::pow(10.0, e_lo);
        axis.max = std::pow(10.0, e_hi);
        for (int e = e_lo; e <= e_hi; ++e) axis.ticks.push_back(std::pow(10.0, e));
        return axis;
    }
    std::vector<double> candidates;
    for (int e = e_lo - 1; e <= e_hi + 1; ++e)
        for (const double m : {1.0, 2.0, 5.0}) candidates.push_back(m * std::pow(10.0, e));
    // The candidates around the data; a range that is one candidate gets its two neighbours.
    size_t first = 0, last = candidates.size() - 1;
    for (size_t i = 0; i < candidates.size(); ++i)
        if (candidates[i] <= lo * (1 + 1e-9)) first = i;
    for (size_t i = candidates.size(); i-- > 0;)
        if (candidates[i] >= hi * (1 - 1e-9)) last = i;
    if (first == last) {
        if (first > 0) --first;
        if (last + 1 < candidates.size()) ++last;
    }
    axis.min = candidates[first];
    axis.max = candidates[last];
    axis.ticks.assign(candidates.begin() + long(first), candidates.begin() + long(last) + 1);
    return axis;
}

std::string format_tick(double value) {
    if (value == 0) return "0";
    return fmt::format("{:.6g}", value);
}

namespace {

// Okabe & Ito (2008), "Color Universal Design": distinguishable with any colour-vision deficiency.
constexpr std::array<const char*, 8> kPalette = {"#0072B2", "#D55E00", "#009E73", "#CC79A7",
                                                 "#E69F00", "#56B4E9", "#000000", "#F0E442"};

std::string marker(size_t shape, double x, double y, const char* colour, const std::string& title) {
    const double r = 4.5;
    std::string body;
    switch (shape % 4) {
        case 0:
            body = fmt::format(R"(<circle cx="{:.2f}" cy="{:.2f}" r="{:.1f}")", x, y, r);
            break;
        case 1:
            body = fmt::format(R"(<rect x="{:.2f}" y="{:.2f}" width="{:.1f}" height="{:.1f}")",
                               x - r, y - r, 2 * r, 2 * r);
            break;
        case 2:
            body = fmt::format(R"(<polygon points="{:.2f},{:.2f} {:.2f},{:.2f} {:.2f},{:.2f}")", x,
                               y - 1.2 * r, x + 1.1 * r, y + 0.8 * r, x - 1.1 * r, y + 0.8 * r);
            break;
        default:
            body = fmt::format(
                R"(<polygon points="{:.2f},{:.2f} {:.2f},{:.2f} {:.2f},{:.2f} {:.2f},{:.2f}")", x,
                y - 1.3 * r, x + 1.3 * r, y, x, y + 1.3 * r, x - 1.3 * r, y);
    }
    body += fmt::format(R"( fill="{}" stroke="#ffffff" stroke-width="1")", colour);
    if (title.empty()) return body + "/>\n";
    return body + "><title>" + xml_escape(title) + "</title></" +
           body.substr(1, body.find(' ') - 1) + ">\n";
}

bool plottable(double value, bool log) {
    return std::isfinite(value) && (!log || value > 0);
}

}  // namespace

std::string svg_line_plot(const PlotOptions& options, const std::vector<PlotSeries>& series) {
    // Data ranges over the points that can be drawn.
    double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
    double y_lo = x_lo, y_hi = -x_lo;
    std::vector<std::vector<PlotPoint>> kept(series.size());
    for (size_t s = 0; s < series.size(); ++s) {
        for (const PlotPoint& p : series[s].points) {
            if (!plottable(p.x, options.x.log) || !plottable(p.y, options.y.log)) continue;
            kept[s].push_back(p);
            x_lo = std::min(x_lo, p.x), x_hi = std::max(x_hi, p.x);
            y_lo = std::min(y_lo, p.y), y_hi = std::max(y_hi, p.y);
        }
        std::stable_sort(kept[s].begin(), kept[s].end(),
                         [](const PlotPoint& a, const PlotPoint& b) { return a.x < b.x; });
    }
    const bool empty = !(x_lo <= x_hi);
    if (empty) {
        x_lo = options.x.log ? 0.1 : 0, x_hi = 1;
        y_lo = options.y.log ? 0.1 : 0, y_hi = 1;
    }
    const AxisTicks xa = options.x.log ? log_axis(x_lo, x_hi) : linear_axis(x_lo, x_hi);
    const AxisTicks ya = options.y.log ? log_axis(y_lo, y_hi) : linear_axis(y_lo, y_hi);

    const double width = options.width, height = options.height;
    const double left = 70, right = width - 170, top = 36, bottom = height - 52;
    auto map = [](double v, const AxisTicks& a, bool log, double from, double to) {
        const double f =
            log ? (std::log10(v) - std::log10(a.min)) / (std::log10(a.max) - std::log10(a.min))
                : (v - a.min) / (a.max - a.min);
        return from + f * (to - from);
    };
    auto px = [&](double x) { return map(x, xa, options.x.log, left, right); };
    auto py = [&](double y) { return map(y, ya, options.y.log, bottom, top); };

    std::string svg = fmt::format(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" "
        "viewBox=\"0 0 {0} {1}\" font-family=\"sans-serif\" font-size=\"12\">\n"
        "<rect x=\"0\" y=\"0\" width=\"{0}\" height=\"{1}\" fill=\"#ffffff\"/>\n",
        options.width, options.height);
    svg += fmt::format(
        "<text x=\"{:.1f}\" y=\"22\" text-anchor=\"middle\" font-size=\"14\" "
        "font-weight=\"bold\">{}</text>\n",
        (left + right) / 2, xml_escape(options.title));

    // Grid and ticks.
    svg += "<g class=\"x-ticks\" stroke=\"#dddddd\">\n";
    for (const double t : xa.ticks)
        svg += fmt::format(
            "<line x1=\"{0:.2f}\" y1=\"{1:.2f}\" x2=\"{0:.2f}\" y2=\"{2:.2f}\"/>"
            "<text x=\"{0:.2f}\" y=\"{3:.2f}\" text-anchor=\"middle\" stroke=\"none\" "
            "fill=\"#000000\">{4}</text>\n",
            px(t), top, bottom + 5, bottom + 19, format_tick(t));
    svg += "</g>\n<g class=\"y-ticks\" stroke=\"#dddddd\">\n";
    for (const double t : ya.ticks)
        svg += fmt::format(
            "<line x1=\"{0:.2f}\" y1=\"{1:.2f}\" x2=\"{2:.2f}\" y2=\"{1:.2f}\"/>"
            "<text x=\"{3:.2f}\" y=\"{4:.2f}\" text-anchor=\"end\" stroke=\"none\" "
            "fill=\"#000000\">{5}</text>\n",
            left - 5, py(t), right, left - 8, py(t) + 4, format_tick(t));
    svg += "</g>\n";
    svg += fmt::format(
        "<rect x=\"{:.2f}\" y=\"{:.2f}\" width=\"{:.2f}\" height=\"{:.2f}\" fill=\"none\" "
        "stroke=\"#000000\"/>\n",
        left, top, right - left, bottom - top);
    svg += fmt::format(
        "<text class=\"x-label\" x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{}</text>\n",
        (left + right) / 2, height - 12, xml_escape(options.x.label));
    svg += fmt::format(
        "<text class=\"y-label\" x=\"0\" y=\"0\" text-anchor=\"middle\" "
        "transform=\"translate(16 {:.1f}) rotate(-90)\">{}</text>\n",
        (top + bottom) / 2, xml_escape(options.y.label));
    if (empty)
        svg += fmt::format(
            "<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" fill=\"#777777\">no data to "
            "plot</text>\n",
            (left + right) / 2, (top + bottom) / 2);

    // Series, then the legend.
    for (size_t s = 0; s < series.size(); ++s) {
        const char* colour = kPalette[s % kPalette.size()];
        svg += fmt::format("<g class=\"series\" data-name=\"{}\">\n", xml_escape(series[s].name));
        if (kept[s].size() > 1) {
            std::string points;
            for (const PlotPoint& p : kept[s])
                points +=
                    fmt::format("{}{:.2f},{:.2f}", points.empty() ? "" : " ", px(p.x), py(p.y));
            svg += fmt::format(
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"2\"/>\n",
                points, colour);
        }
        for (const PlotPoint& p : kept[s]) {
            std::string title = series[s].name;
            if (!p.label.empty()) title += " " + p.label;
            title += fmt::format(": {}, {}", format_tick(p.x), format_tick(p.y));
            svg += marker(s, px(p.x), py(p.y), colour, title);
        }
        svg += "</g>\n";
    }
    svg += "<g class=\"legend\">\n";
    for (size_t s = 0; s < series.size(); ++s) {
        const char* colour = kPalette[s % kPalette.size()];
        const double y = top + 12 + 22.0 * double(s);
        svg += fmt::format(
            "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" "
            "stroke-width=\"2\"/>\n",
            right + 14, y, right + 40, y, colour);
        svg += marker(s, right + 27, y, colour, "");
        svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\">{}</text>\n", right + 48, y + 4,
                           xml_escape(series[s].name));
    }
    svg += "</g>\n</svg>\n";
    return svg;
}

}  // namespace btf::quality
