// SPDX-License-Identifier: MIT
#include "btf/quality/render_compare.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <fmt/format.h>

#include "btf/core/color.h"
#include "btf/quality/colormap.h"
#include "btf/quality/metrics.h"
#include "btf/util/error.h"

namespace btf::quality {

namespace {

/// The value with floor(q × n) values below it (report.cpp rounds the rank to the nearest).
double lower_percentile(std::vector<float> values, double q) {
    if (values.empty()) return 0;
    const size_t k = std::min(values.size() - 1, size_t(q * double(values.size())));
    std::nth_element(values.begin(), values.begin() + ptrdiff_t(k), values.end());
    return values[k];
}

}  // namespace

Image tone_map(const Image& linear, double exposure) {
    Image out(linear.width(), linear.height(), 3);
    const float gain = float(std::exp2(exposure));
    const float* in = linear.data();
    float* o = out.data();
    const size_t n = size_t(linear.num_pixels());
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            const float x = std::max(0.0f, in[i * linear.channels() + c] * gain);
            o[i * 3 + c] = std::clamp((x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f),
                                      0.0f, 1.0f);
        }
    return out;
}

RenderComparison compare_renders(const Image& a, const Image& b, double exposure, double heat_max) {
    if (a.width() != b.width() || a.height() != b.height())
        throw Error("compare_renders: the images differ in size");
    return compare_displays(tone_map(a, exposure), tone_map(b, exposure), heat_max);
}

RenderComparison compare_displays(const Image& ta, const Image& tb, double heat_max) {
    if (ta.width() != tb.width() || ta.height() != tb.height())
        throw Error(fmt::format("the images differ in size: {} × {} and {} × {}", ta.width(),
                                ta.height(), tb.width(), tb.height()));
    const int64_t n = ta.num_pixels();
    const size_t count = static_cast<size_t>(n);
    std::vector<float> de(count), ya(count), yb(count);
    double squared = 0;
    for (int64_t i = 0; i < n; ++i) {
        const int x = int(i % ta.width()), y = int(i / ta.width());
        const Rgb ca = ta.rgb(x, y), cb = tb.rgb(x, y);
        de[size_t(i)] = float(ciede2000(rgb_to_lab(ca), rgb_to_lab(cb)));
        ya[size_t(i)] = linear_to_srgb(luminance(ca));
        yb[size_t(i)] = linear_to_srgb(luminance(cb));
        const float dr = ca.r - cb.r, dg = ca.g - cb.g, db = ca.b - cb.b;
        squared += double(dr) * dr + double(dg) * dg + double(db) * db;
    }
    RenderComparison r;
    double sum = 0;
    for (float d : de) sum += d;
    r.de2000_mean = n ? sum / double(n) : 0;
    r.de2000_p95 = lower_percentile(de, 0.95);
    r.ssim = mssim(ya.data(), yb.data(), ta.width(), ta.height());
    const double mse = n ? squared / (3.0 * double(n)) : 0;
    r.psnr = mse > 0 ? 10 * std::log10(1 / mse) : INFINITY;
    r.heat_max = heat_max > 0 ? heat_max : nice_ceil(std::max(1.0, lower_percentile(de, 0.99)));
    r.heat_map = quality::heat_map(de, ta.width(), ta.height(), r.heat_max);
    r.de2000 = std::move(de);
    return r;
}

nlohmann::json metrics_json(const RenderComparison& c) {
    return {{"de2000_mean", c.de2000_mean},
            {"de2000_p95", c.de2000_p95},
            {"ssim", c.ssim},
            {"psnr_db", std::isfinite(c.psnr) ? nlohmann::json(c.psnr) : nlohmann::json(nullptr)},
            {"heat_map_max", c.heat_max}};
}

std::string summary(const RenderComparison& c) {
    return fmt::format("ΔE00 mean {:.3f}, 95th percentile {:.3f}; SSIM {:.4f}; PSNR {:.2f} dB",
                       c.de2000_mean, c.de2000_p95, c.ssim, c.psnr);
}

Image side_by_side(const Image& a, const Image& b, const Image& heat) {
    constexpr int kGap = 4;
    const int w = a.width(), h = a.height();
    Image out(3 * w + 2 * kGap, h, 3, 1.0f);
    const Image* parts[3] = {&a, &b, &heat};
    for (int p = 0; p < 3; ++p)
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) out.set_rgb(p * (w + kGap) + x, y, parts[p]->rgb(x, y));
    return out;
}

}  // namespace btf::quality
