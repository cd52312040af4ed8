// SPDX-License-Identifier: MIT
#include "btf/quality/metrics.h"

#include <tbb/enumerable_thread_specific.h>
#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>

#include "btf/core/image.h"
#include "btf/io/source.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::quality {

// ---- SSIM ---------------------------------------------------------------------------------------

namespace {

// Normalized 1-D Gaussian of `taps` taps centred at (taps - 1) / 2.
std::vector<double> gaussian_taps(int taps, double sigma) {
    std::vector<double> g(static_cast<size_t>(taps));
    const double centre = 0.5 * (taps - 1);
    double sum = 0;
    for (int k = 0; k < taps; ++k) {
        const double d = k - centre;
        g[size_t(k)] = std::exp(-d * d / (2 * sigma * sigma));
        sum += g[size_t(k)];
    }
    for (double& v : g) v /= sum;
    return g;
}

}  // namespace

double mssim(const float* reference, const float* test, int width, int height,
             const SsimParams& params) {
    check(width > 0 && height > 0, "mssim: the planes are {}×{}, expected at least 1×1", width,
          height);
    check(params.window > 0 && params.window % 2 == 1,
          "mssim: window {} is not a positive odd number of pixels", params.window);
    check(params.sigma > 0 && params.dynamic_range > 0,
          "mssim: sigma ({}) and dynamic range ({}) must be positive", params.sigma,
          params.dynamic_range);
    const int nx = std::min(params.window, width), ny = std::min(params.window, height);
    const std::vector<double> gx = gaussian_taps(nx, params.sigma);
    const std::vector<double> gy = nx == ny ? gx : gaussian_taps(ny, params.sigma);
    const double c1 = std::pow(params.k1 * params.dynamic_range, 2);
    const double c2 = std::pow(params.k2 * params.dynamic_range, 2);
    const int out_w = width - nx + 1;
    const Eigen::Index w = width, ow = out_w;

    // Separable filtering of x, y, x², y², xy: every input row is filtered along the row once into
    // a ring of the last ny rows; each output row filters that ring down the columns.
    std::vector<Eigen::ArrayXd> ring(size_t(5 * ny), Eigen::ArrayXd(ow));
    Eigen::ArrayXd a(w), b(w), product(w);
    auto along_row = [&](const Eigen::ArrayXd& in, Eigen::ArrayXd& out) {
        out = gx[0] * in.head(ow);
        for (int k = 1; k < nx; ++k) out += gx[size_t(k)] * in.segment(k, ow);
    };
    std::array<Eigen::ArrayXd, 5> m;  // μx, μy, E[x²], E[y²], E[xy] of one output row
    double total = 0;
    for (int row = 0; row < height; ++row) {
        a = Eigen::Map<const Eigen::ArrayXf>(reference + row * w, w).cast<double>();
        b = Eigen::Map<const Eigen::ArrayXf>(test + row * w, w).cast<double>();
        Eigen::ArrayXd* slot = &ring[size_t(5 * (row % ny))];
        along_row(a, slot[0]);
        along_row(b, slot[1]);
        product = a.square();
        along_row(product, slot[2]);
        product = b.square();
        along_row(product, slot[3]);
        product = a * b;
        along_row(product, slot[4]);
        if (row < ny - 1) continue;
        const int first = row - ny + 1;  // the output row's top input row
        for (int q = 0; q < 5; ++q) {
            m[size_t(q)] = gy[0] * ring[size_t(5 * (first % ny) + q)];
            for (int k = 1; k < ny; ++k)
                m[size_t(q)] += gy[size_t(k)] * ring[size_t(5 * ((first + k) % ny) + q)];
        }
        const Eigen::ArrayXd mu_xy = m[0] * m[1], mu_xx = m[0].square(), mu_yy = m[1].square();
        total += ((2 * mu_xy + c1) * (2 * (m[4] - mu_xy) + c2) /
                  ((mu_xx + mu_yy + c1) * ((m[2] - mu_xx) + (m[3] - mu_yy) + c2)))
                     .sum();
    }
    return total / (double(out_w) * double(height - ny + 1));
}

// ---- metric selection ---------------------------------------------------------------------------

MetricSelection MetricSelection::parse(const std::string& list, std::vector<std::string>* rest) {
    MetricSelection s;
    s.rmse = s.lab = s.de2000 = s.ssim = false;
    std::stringstream in(list);
    std::string name;
    int named = 0;
    while (std::getline(in, name, ',')) {
        const auto first = name.find_first_not_of(" \t");
        const auto last = name.find_last_not_of(" \t");
        name = first == std::string::npos ? "" : name.substr(first, last - first + 1);
        if (name.empty()) continue;
        ++named;
        if (name == "rmse")
            s.rmse = true;
        else if (name == "lab")
            s.lab = true;
        else if (name == "de2000")
            s.de2000 = true;
        else if (name == "ssim")
            s.ssim = true;
        else if (rest)
            rest->push_back(name);
        else
            fail("unknown metric '{}'; the metrics are rmse, lab, de2000, ssim", name);
    }
    check(named > 0, "no metric named in '{}'; the metrics are rmse, lab, de2000, ssim", list);
    return s;
}

// ---- comparability ------------------------------------------------------------------------------

namespace {

std::string source_name(const BtfSource& source) {
    const SourceInfo& info = source.info();
    return info.path.empty() ? info.format : info.path.string();
}

void check_directions(const std::string& prefix, const char* what, const DirectionSet& ref,
                      const DirectionSet& test) {
    check(ref.size() == test.size(), "{}: {} {}s vs {}", prefix, ref.size(), what, test.size());
    const double min_cos = std::cos(1e-4);
    for (int i = 0; i < ref.size(); ++i)
        check(dot(ref.vector(i), test.vector(i)) >= min_cos,
              "{}: {} {} is at θ {:.4f}°, φ {:.4f}° vs θ {:.4f}°, φ {:.4f}°", prefix, what, i,
              ref[i].theta_deg(), ref[i].phi_deg(), test[i].theta_deg(), test[i].phi_deg());
}

}  // namespace

void check_comparable(const BtfSource& reference, const BtfSource& test) {
    const std::string prefix = source_name(reference) + " vs " + source_name(test);
    check(reference.width() == test.width() && reference.height() == test.height(),
          "{}: extent {}×{} vs {}×{} texels", prefix, reference.width(), reference.height(),
          test.width(), test.height());
    check_directions(prefix, "view", reference.sampling().views, test.sampling().views);
    check_directions(prefix, "light", reference.sampling().lights, test.sampling().lights);
}

// ---- compare ------------------------------------------------------------------------------------

namespace {

constexpr int kHistogramBins = static_cast<int>(kDe2000HistogramMax / kDe2000BinWidth + 0.5);
// cos θ weights of the histogram in fixed point, so that its integer sums are exact and do not
// depend on the order in which threads add them.
constexpr double kWeightScale = double(1 << 20);

struct ImageSums {
    double sse = 0;
    std::array<double, 3> lab{};
    double de_sum = 0, de_max = 0;
    std::array<double, 3> ssim{};  // Y, Cr, Cb
};

struct SsimScratch {
    Image ref, test;
    std::vector<float> planes;  // Y, Cr, Cb of the reference, then of the test
    std::vector<uint32_t> histogram = std::vector<uint32_t>(size_t(kHistogramBins) + 1, 0);
};

double largest_value(const BtfSource& source, Progress& progress) {
    const int nl = source.num_lights();
    const int64_t images = source.sampling().num_images();
    std::vector<float> largest(size_t(images), 0.0f);
    tbb::enumerable_thread_specific<Image> scratch;
    progress.begin("finding the peak", uint64_t(images));
    parallel_for(0, images, [&](int64_t i) {
        Image& image = scratch.local();
        source.read_image(int(i / nl), int(i % nl), image);
        float m = 0;
        for (float v : image.values())
            if (std::isfinite(v)) m = std::max(m, v);
        largest[size_t(i)] = m;
        progress.advance();
    });
    progress.finish();
    const float m = largest.empty() ? 0.0f : *std::max_element(largest.begin(), largest.end());
    return m > 0 ? double(m) : 1.0;
}

bool finite(const Rgb& c) {
    return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b);
}

// Display encoding for SSIM: linear / peak, clamped to [0, 1], sRGB transfer, BT.601 YCbCr.
YCbCr display_ycbcr(const Rgb& c, float inv_peak) {
    auto encode = [inv_peak](float v) {
        return linear_to_srgb(std::clamp(v * inv_peak, 0.0f, 1.0f));
    };
    return rgb_to_ycbcr({encode(c.r), encode(c.g), encode(c.b)});
}

}  // namespace

Metrics compare(const BtfSource& reference, const BtfSource& test, const CompareOptions& options,
                Progress& progress) {
    const auto start = std::chrono::steady_clock::now();
    check_comparable(reference, test);
    const MetricSelection& sel = options.metrics;
    check(std::isfinite(options.peak) && options.peak >= 0,
          "{} vs {}: peak {} is not a positive number", source_name(reference), source_name(test),
          options.peak);

    Metrics m;
    m.selection = sel;
    m.cos_weighted = options.cos_weight;
    const int w = reference.width(), h = reference.height();
    const Sampling& sampling = reference.sampling();
    const int nl = sampling.num_lights();
    m.texels = int64_t(w) * h;
    m.images = sampling.num_images();
    m.peak = options.peak > 0 ? options.peak : 1.0;
    if (options.peak == 0 && reference.info().hdr && (sel.rmse || sel.ssim))
        m.peak = largest_value(reference, progress);
    const float inv_peak = float(1.0 / m.peak);

    // Per-view weights: cos θ (or 1) for the means, and in fixed point for the histogram.
    std::vector<double> view_weight(size_t(sampling.num_views()), 1.0);
    std::vector<int64_t> view_weight_fixed(view_weight.size(), 1);
    if (options.cos_weight) {
        for (int v = 0; v < sampling.num_views(); ++v) {
            view_weight[size_t(v)] = std::max(0.0, std::cos(sampling.views[v].theta));
            view_weight_fixed[size_t(v)] = std::llround(view_weight[size_t(v)] * kWeightScale);
        }
    }

    const std::string ref_name = source_name(reference), test_name = source_name(test);
    const size_t texels = size_t(m.texels);
    std::vector<ImageSums> sums(size_t(m.images));
    std::vector<int64_t> histogram(sel.de2000 ? size_t(kHistogramBins) + 1 : 0, 0);
    std::mutex histogram_mutex;
    tbb::enumerable_thread_specific<SsimScratch> scratch;

    progress.begin("comparing", uint64_t(m.images));
    parallel_for(0, m.images, [&](int64_t i) {
        const int view = int(i / nl), light = int(i % nl);
        SsimScratch& s = scratch.local();
        reference.read_image(view, light, s.ref);
        test.read_image(view, light, s.test);
        auto check_shape = [&](const Image& image, const std::string& name) {
            check(image.width() == w && image.height() == h && image.channels() == 3,
                  "{}: image (view {}, light {}) is {}×{}×{}, expected {}×{}×3", name, view, light,
                  image.width(), image.height(), image.channels(), w, h);
        };
        check_shape(s.ref, ref_name);
        check_shape(s.test, test_name);
        const float* a = s.ref.data();
        const float* b = s.test.data();
        ImageSums r;
        if (sel.ssim) s.planes.resize(6 * texels);
        float* const planes = s.planes.data();
        int lo = kHistogramBins + 1, hi = -1;
        for (size_t t = 0; t < texels; ++t) {
            const Rgb ca{a[3 * t], a[3 * t + 1], a[3 * t + 2]};
            const Rgb cb{b[3 * t], b[3 * t + 1], b[3 * t + 2]};
            if (!(finite(ca) && finite(cb)))
                fail("{}: image (view {}, light {}) holds a non-finite value at texel ({}, {})",
                     finite(ca) ? test_name : ref_name, view, light, t % size_t(w), t / size_t(w));
            if (sel.rmse) {
                const double dr = double(ca.r) - cb.r, dg = double(ca.g) - cb.g,
                             db = double(ca.b) - cb.b;
                r.sse += dr * dr + dg * dg + db * db;
            }
            if (sel.lab || sel.de2000) {
                const Lab la = rgb_to_lab(ca), lb = rgb_to_lab(cb);
                if (sel.lab) {
                    r.lab[0] += std::abs(la.l - lb.l);
                    r.lab[1] += std::abs(la.a - lb.a);
                    r.lab[2] += std::abs(la.b - lb.b);
                }
                if (sel.de2000) {
                    const double de = ciede2000(la, lb);
                    r.de_sum += de;
                    r.de_max = std::max(r.de_max, de);
                    const int bin = de < kDe2000HistogramMax
                                        ? std::min(int(de / kDe2000BinWidth), kHistogramBins - 1)
                                        : kHistogramBins;
                    ++s.histogram[size_t(bin)];
                    lo = std::min(lo, bin);
                    hi = std::max(hi, bin);
                }
            }
            if (sel.ssim) {
                const YCbCr ya = display_ycbcr(ca, inv_peak), yb = display_ycbcr(cb, inv_peak);
                planes[t] = ya.y;
                planes[texels + t] = ya.cr;
                planes[2 * texels + t] = ya.cb;
                planes[3 * texels + t] = yb.y;
                planes[4 * texels + t] = yb.cr;
                planes[5 * texels + t] = yb.cb;
            }
        }
        if (sel.ssim)
            for (int c = 0; c < 3; ++c)
                r.ssim[size_t(c)] =
                    mssim(planes + c * texels, planes + (3 + c) * texels, w, h, SsimParams{});
        if (sel.de2000 && hi >= lo) {
            const int64_t weight = view_weight_fixed[size_t(view)];
            std::lock_guard lock(histogram_mutex);
            for (int bin = lo; bin <= hi; ++bin) {
                histogram[size_t(bin)] += int64_t(s.histogram[size_t(bin)]) * weight;
                s.histogram[size_t(bin)] = 0;
            }
        }
        sums[size_t(i)] = r;
        progress.advance();
    });
    progress.finish();

    // Reduction in image order: the same sums for any number of threads.
    double weight_sum = 0, sse = 0, de_sum = 0;
    std::array<double, 3> lab{}, ssim{};
    for (int64_t i = 0; i < m.images; ++i) {
        const double wt = view_weight[size_t(i / nl)];
        const ImageSums& r = sums[size_t(i)];
        weight_sum += wt;
        sse += wt * r.sse;
        de_sum += wt * r.de_sum;
        for (int c = 0; c < 3; ++c) {
            lab[size_t(c)] += wt * r.lab[size_t(c)];
            ssim[size_t(c)] += wt * r.ssim[size_t(c)];
        }
        m.de2000_max = std::max(m.de2000_max, r.de_max);
    }
    check(weight_sum > 0, "{} vs {}: every view is at θ = 90°: cos θ weighting leaves no weight",
          ref_name, test_name);
    const double texel_weight = weight_sum * double(m.texels);
    if (sel.rmse) {
        m.rmse = std::sqrt(sse / (3 * texel_weight));
        m.psnr =
            m.rmse > 0 ? 20 * std::log10(m.peak / m.rmse) : std::numeric_limits<double>::infinity();
    }
    if (sel.lab)
        for (int c = 0; c < 3; ++c) m.lab_mae[size_t(c)] = lab[size_t(c)] / texel_weight;
    if (sel.de2000) {
        m.de2000_mean = de_sum / texel_weight;
        int64_t total = 0;
        for (int64_t count : histogram) total += count;
        int64_t cumulative = 0;
        m.de2000_p95 = m.de2000_max;
        for (int bin = 0; bin < kHistogramBins; ++bin) {
            cumulative += histogram[size_t(bin)];
            if ((long double)cumulative >= 0.95L * (long double)total) {
                m.de2000_p95 = std::min((bin + 1) * kDe2000BinWidth, m.de2000_max);
                break;
            }
        }
    }
    if (sel.ssim) {
        for (int c = 0; c < 3; ++c) m.ssim_ycrcb[size_t(c)] = ssim[size_t(c)] / weight_sum;
        m.ssim_luminance = m.ssim_ycrcb[0];
    }
    if (options.per_image) {
        m.images_detail.resize(size_t(m.images));
        for (int64_t i = 0; i < m.images; ++i) {
            ImageMetrics& d = m.images_detail[size_t(i)];
            const ImageSums& r = sums[size_t(i)];
            d.view = int(i / nl);
            d.light = int(i % nl);
            if (sel.rmse) d.rmse = std::sqrt(r.sse / (3 * double(m.texels)));
            if (sel.de2000) d.de2000_mean = r.de_sum / double(m.texels);
            if (sel.ssim) d.ssim_luminance = r.ssim[0];
        }
    }
    m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return m;
}

}  // namespace btf::quality
