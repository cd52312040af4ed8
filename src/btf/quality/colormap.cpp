// SPDX-License-Identifier: MIT
#include "btf/quality/colormap.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "btf/core/color.h"
#include "btf/quality/plot.h"
#include "btf/util/error.h"

namespace btf::quality {

namespace {

constexpr int kTableSize = 256;
constexpr double kHueStart = 295, kHueEnd = 100;      // degrees in CIELab (a*, b*)
constexpr double kChromaStart = 45, kChromaEnd = 75;  // wanted; less where sRGB cannot

bool in_gamut(const Rgb& c) {
    constexpr float eps = 1e-5f;
    return c.r >= -eps && c.g >= -eps && c.b >= -eps && c.r <= 1 + eps && c.g <= 1 + eps &&
           c.b <= 1 + eps;
}

Rgb clamp01(const Rgb& c) {
    return {std::clamp(c.r, 0.0f, 1.0f), std::clamp(c.g, 0.0f, 1.0f), std::clamp(c.b, 0.0f, 1.0f)};
}

// The colour at t with the largest chroma up to the wanted one that sRGB can show (bisection).
Rgb design(double t) {
    const double l = kColormapLightness[0] + (kColormapLightness[1] - kColormapLightness[0]) * t;
    const double hue = radians(kHueStart + (kHueEnd - kHueStart) * t);
    const double wanted = kChromaStart + (kChromaEnd - kChromaStart) * t;
    auto at = [&](double chroma) {
        return lab_to_rgb(Lab{l, chroma * std::cos(hue), chroma * std::sin(hue)});
    };
    if (in_gamut(at(wanted))) return clamp01(at(wanted));
    double lo = 0, hi = wanted;
    for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (in_gamut(at(mid)) ? lo : hi) = mid;
    }
    return clamp01(at(lo));
}

const std::array<Rgb, kTableSize>& table() {
    static const std::array<Rgb, kTableSize> entries = [] {
        std::array<Rgb, kTableSize> e;
        for (int i = 0; i < kTableSize; ++i) e[size_t(i)] = design(double(i) / (kTableSize - 1));
        return e;
    }();
    return entries;
}

}  // namespace

Rgb colormap(double t) {
    if (!(t > 0)) t = 0;  // NaN too
    if (t > 1) t = 1;
    const std::array<Rgb, kTableSize>& e = table();
    const double f = t * (kTableSize - 1);
    const int i = std::min(int(f), kTableSize - 2);
    const float w = float(f - i);
    const Rgb& a = e[size_t(i)];
    const Rgb& b = e[size_t(i) + 1];
    return {a.r + (b.r - a.r) * w, a.g + (b.g - a.g) * w, a.b + (b.b - a.b) * w};
}

std::string srgb_hex(const Rgb& linear) {
    auto code = [](float v) {
        return int(std::lround(255.0f * linear_to_srgb(std::clamp(v, 0.0f, 1.0f))));
    };
    return fmt::format("#{:02x}{:02x}{:02x}", code(linear.r), code(linear.g), code(linear.b));
}

Image heat_map(const std::vector<float>& values, int width, int height, double max) {
    check(width > 0 && height > 0 && int64_t(values.size()) == int64_t(width) * height,
          "heat map: {} values for a {}×{} image", values.size(), width, height);
    check(max > 0 && std::isfinite(max), "heat map: scale maximum {} is not positive", max);
    Image image(width, height, 3);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            image.set_rgb(x, y, colormap(values[size_t(y) * size_t(width) + size_t(x)] / max));
    return image;
}

double nice_ceil(double value) {
    if (!(value > 0) || !std::isfinite(value)) return 1;
    const double power = std::pow(10.0, std::floor(std::log10(value)));
    for (const double m : {1.0, 2.0, 2.5, 5.0, 10.0})
        if (m * power >= value * (1 - 1e-12)) return m * power;
    return 10 * power;
}

std::string colorbar_svg(double max, const std::string& label, int width, int height) {
    check(max > 0 && std::isfinite(max), "colour bar: maximum {} is not positive", max);
    const double top = 34, bottom = height - 14, left = 12, right = 36;
    std::string svg = fmt::format(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" "
        "viewBox=\"0 0 {0} {1}\" font-family=\"sans-serif\" font-size=\"12\">\n"
        "<rect x=\"0\" y=\"0\" width=\"{0}\" height=\"{1}\" fill=\"#ffffff\"/>\n"
        "<defs><linearGradient id=\"ramp\" x1=\"0\" y1=\"1\" x2=\"0\" y2=\"0\">\n",
        width, height);
    constexpr int kStops = 32;
    for (int i = 0; i <= kStops; ++i) {
        const double t = double(i) / kStops;
        svg +=
            fmt::format("<stop offset=\"{:.4f}\" stop-color=\"{}\"/>\n", t, srgb_hex(colormap(t)));
    }
    svg += "</linearGradient></defs>\n";
    svg += fmt::format("<text x=\"{:.1f}\" y=\"18\" font-weight=\"bold\">{}</text>\n", left - 6,
                       xml_escape(label));
    svg += fmt::format(
        "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"url(#ramp)\" "
        "stroke=\"#000000\"/>\n",
        left, top, right - left, bottom - top);
    svg += "<g class=\"ticks\">\n";
    for (const double t : linear_axis(0, max).ticks) {
        if (t > max * (1 + 1e-9)) continue;
        const double y = bottom + (top - bottom) * (t / max);
        // Values above the top were drawn in the top colour: say so at that tick.
        const std::string text = (t >= max * (1 - 1e-9) ? "\u2265 " : "") + format_tick(t);
        svg += fmt::format(
            "<line x1=\"{0:.1f}\" y1=\"{1:.2f}\" x2=\"{2:.1f}\" y2=\"{1:.2f}\" stroke=\"#000000\"/>"
            "<text x=\"{3:.1f}\" y=\"{4:.2f}\" data-value=\"{5}\">{6}</text>\n",
            right, y, right + 5, right + 8, y + 4, format_tick(t), xml_escape(text));
    }
    svg += "</g>\n</svg>\n";
    return svg;
}

}  // namespace btf::quality
