// SPDX-License-Identifier: MIT
#include "btf/core/light_sampler.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "btf/core/color.h"
#include "btf/core/hemisphere.h"
#include "btf/util/error.h"

namespace btf {

namespace {

// ξ clamped into [0, 1); NaN becomes 0.
double unit_interval(double xi) {
    if (!(xi > 0)) return 0;
    return std::min(xi, 0x1.fffffffffffffp-1);
}

// Index of the texel containing coordinate `u` (wrapping) among n.
int wrapped_texel(double u, int n) {
    if (!std::isfinite(u)) return 0;
    u -= std::floor(u);
    return std::clamp(static_cast<int>(u * n), 0, n - 1);
}

// The step j of a non-decreasing CDF given as a function cdf(0..n) with cdf(j) ≤ x < cdf(j + 1),
// and the position of x inside it in [0, 1]. Bisection down to 64 steps, then a linear scan: a
// scan issues its loads independently of each other, while every probe of a bisection waits for
// the previous one's cache miss (tables are read in random order). With R = 32 it is a scan.
struct Step {
    int index;
    double offset;
};
template <typename Cdf>
Step invert(const Cdf& cdf, int n, double x) {
    int lo = 0, hi = n;  // cdf(lo) ≤ x; x < cdf(hi) unless rounding put x at the top
    while (hi - lo > 64) {
        const int mid = (lo + hi) / 2;
        (cdf(mid) <= x ? lo : hi) = mid;
    }
    double low = cdf(lo), high = cdf(lo + 1);
    while (lo + 1 < hi && high <= x) {
        ++lo;
        low = high;
        high = cdf(lo + 1);
    }
    const double width = high - low;
    const double offset = width > 0 ? (x - low) / width : 0.5;
    return {lo, std::clamp(offset, 0.0, 1.0)};
}

// The centre directions of the cells of an R × R grid over the square, row-major (row = v).
std::vector<Vec3> cell_centres(int resolution) {
    std::vector<Vec3> centres(size_t(resolution) * resolution);
    for (int r = 0; r < resolution; ++r)
        for (int c = 0; c < resolution; ++c)
            centres[size_t(r) * resolution + c] =
                square_to_hemisphere({(c + 0.5) / resolution, (r + 0.5) / resolution});
    return centres;
}

}  // namespace

// The tables serving one (uv, ωo) and their weights.
struct LightSampler::Blend {
    std::array<const float*, 3> table{};
    std::array<double, 3> weight{};
    int count = 0;
    double total = 0;  // Σ weight (1 up to rounding)
};

LightSampler::LightSampler(const Material& material, const LightSamplerOptions& options)
    : m_material(material), m_options(options) {
    const LightSamplerOptions& o = options;
    check(o.tile_size >= 1 && o.tile_size <= (1 << 16),
          "light sampler: tile size {} out of range [1, 65536]", o.tile_size);
    check(o.resolution >= 1 && o.resolution <= 1024,
          "light sampler: resolution {} out of range [1, 1024]", o.resolution);
    check(o.points_per_side >= 1 && o.points_per_side <= 64,
          "light sampler: points per side {} out of range [1, 64]", o.points_per_side);
    check(o.uniform_fraction > 0 && o.uniform_fraction <= 1,
          "light sampler: uniform fraction {} out of range (0, 1]", o.uniform_fraction);
    check(o.memory_budget > 0, "light sampler: memory budget {} bytes is not positive",
          o.memory_budget);
    const int width = material.width(), height = material.height();
    check(width >= 1 && height >= 1, "light sampler: the material has no texels ({}×{})", width,
          height);
    m_views = material.sampling().num_views();
    check(m_views >= 1, "light sampler: the material has no views");

    // Double the tile until every table fits the budget (or one tile covers the material).
    m_tile = o.tile_size;
    auto tiles = [&](int t) { return int64_t((width + t - 1) / t) * ((height + t - 1) / t); };
    while (tiles(m_tile) * m_views * table_bytes() > o.memory_budget &&
           m_tile < std::max(width, height))
        m_tile *= 2;
    m_tiles_x = (width + m_tile - 1) / m_tile;
    m_tiles_y = (height + m_tile - 1) / m_tile;
    const int64_t slots = int64_t(m_tiles_x) * m_tiles_y * m_views;
    m_tables = std::make_unique<std::atomic<const float*>[]>(size_t(slots));
    m_centres = cell_centres(o.resolution);
    if (o.view_blend == ViewBlend::kBarycentric)
        m_views_interpolator = std::make_unique<AngularInterpolator>(material.sampling().views);
    for (int64_t i = 0; i < slots; ++i) m_tables[i].store(nullptr, std::memory_order_relaxed);
}

LightSampler::~LightSampler() {
    const int64_t slots = int64_t(m_tiles_x) * m_tiles_y * m_views;
    for (int64_t i = 0; i < slots; ++i) delete[] m_tables[i].load(std::memory_order_acquire);
}

int64_t LightSampler::table_bytes() const {
    const int64_t n = m_options.resolution + 1;
    return n * n * int64_t(sizeof(float));
}

LightSampler::Blend LightSampler::blend(const Uv& uv, const Vec3& wo) const {
    const int x = wrapped_texel(uv.u, m_material.width());
    const int y = wrapped_texel(uv.v, m_material.height());
    const int tile = (y / m_tile) * m_tiles_x + x / m_tile;
    Blend b;
    if (m_views_interpolator) {
        const AngularWeights w = m_views_interpolator->weights(wo);
        for (int k = 0; k < w.count; ++k)
            if (w.weight[k] > 0) {
                b.table[b.count] = table(tile, w.index[k]);
                b.weight[b.count] = w.weight[k];
                b.total += w.weight[k];
                ++b.count;
            }
    }
    if (b.count == 0) {
        const int view = std::max(m_material.sampling().views.nearest(wo), 0);
        b.table[0] = table(tile, view);
        b.weight[0] = b.total = 1;
        b.count = 1;
    }
    return b;
}

const float* LightSampler::table(int tile, int view) const {
    const float* t = m_tables[int64_t(tile) * m_views + view].load(std::memory_order_acquire);
    return t ? t : build(tile, view);
}

// Table layout, (R + 1)² floats: the marginal CDF over rows (R + 1 entries from 0 to 1), then for
// each row r its conditional CDF over columns (R + 1 entries from 0 to 1).
const float* LightSampler::build(int tile, int view) const {
    const int R = m_options.resolution;
    const int width = m_material.width(), height = m_material.height();
    const int x0 = (tile % m_tiles_x) * m_tile, y0 = (tile / m_tiles_x) * m_tile;
    const int tw = std::min(m_tile, width - x0), th = std::min(m_tile, height - y0);
    const int kx = std::min(m_options.points_per_side, tw);
    const int ky = std::min(m_options.points_per_side, th);
    // Points on texel corners (integer coordinates), evenly spread: bilinear evaluation there
    // averages the 2 × 2 texels around the corner.
    std::vector<Uv> points;
    points.reserve(size_t(kx) * ky);
    for (int j = 0; j < ky; ++j)
        for (int i = 0; i < kx; ++i) {
            const double px = std::floor(x0 + (2.0 * i + 1) * tw / (2.0 * kx) + 0.5);
            const double py = std::floor(y0 + (2.0 * j + 1) * th / (2.0 * ky) + 0.5);
            points.push_back({px / width, py / height});
        }
    const Vec3 wo = m_material.sampling().views.vector(view);

    // Queries cell by cell, so that consecutive queries share their directions.
    thread_local std::vector<Query> queries;
    thread_local std::vector<Rgb> values;
    queries.clear();
    for (const Vec3& wi : m_centres)
        for (const Uv& p : points) queries.push_back({p, wi, wo});
    values.resize(queries.size());
    m_material.eval_batch(queries, values);

    std::vector<double> p(size_t(R) * R);
    double total = 0;
    for (size_t cell = 0; cell < p.size(); ++cell) {
        double sum = 0;
        for (size_t k = 0; k < points.size(); ++k)
            sum += luminance(values[cell * points.size() + k]);
        const double mean = sum / double(points.size());
        p[cell] = std::isfinite(mean) && mean > 0 ? mean : 0.0;
        total += p[cell];
    }
    const double eps = m_options.uniform_fraction, uniform = 1.0 / (double(R) * R);
    for (double& q : p)
        q = total > 0 && std::isfinite(total) ? (1 - eps) * q / total + eps * uniform : uniform;

    // Every cell has probability ≥ ε / R² > 0, so no row total is zero.
    auto table = std::make_unique<float[]>(size_t(R + 1) * (R + 1));
    std::vector<double> rows(size_t(R) + 1, 0.0);  // cumulative row totals
    for (int r = 0; r < R; ++r) {
        const double* q = p.data() + size_t(r) * R;
        double row = 0;
        for (int c = 0; c < R; ++c) row += q[c];
        float* conditional = table.get() + size_t(R + 1) * (r + 1);
        double acc = 0;
        conditional[0] = 0;
        for (int c = 0; c + 1 < R; ++c)
            conditional[c + 1] = static_cast<float>((acc += q[c]) / row);
        conditional[R] = 1;
        rows[r + 1] = rows[r] + row;
    }
    float* marginal = table.get();
    for (int r = 0; r < R; ++r) marginal[r] = static_cast<float>(rows[r] / rows[R]);
    marginal[R] = 1;

    const float* expected = nullptr;
    std::atomic<const float*>& slot = m_tables[int64_t(tile) * m_views + view];
    if (slot.compare_exchange_strong(expected, table.get(), std::memory_order_acq_rel,
                                     std::memory_order_acquire)) {
        m_built.fetch_add(1, std::memory_order_relaxed);
        return table.release();
    }
    return expected;  // another thread published the same table first
}

double LightSampler::blend_pdf(const Blend& b, const Vec3& wi) const {
    if (!(wi.z >= 0)) return 0;
    const int R = m_options.resolution;
    const SquarePoint s = hemisphere_to_square(wi);
    const int c = std::min(static_cast<int>(s.u * R), R - 1);
    const int r = std::min(static_cast<int>(s.v * R), R - 1);
    double p = 0;
    for (int k = 0; k < b.count; ++k) {
        const float* t = b.table[k];
        const float* conditional = t + size_t(R + 1) * (r + 1);
        p += b.weight[k] * (double(t[r + 1]) - double(t[r])) *
             (double(conditional[c + 1]) - double(conditional[c]));
    }
    return p / b.total * (double(R) * R) / (2 * kPi);
}

LightSample LightSampler::draw(const Blend& b, double xi1, double xi2) const {
    const int R = m_options.resolution;
    // The blended marginal CDF F(r) = Σ_k w_k M_k(r), from 0 to Σ_k w_k.
    const auto marginal = [&](int r) {
        double f = 0;
        for (int k = 0; k < b.count; ++k) f += b.weight[k] * double(b.table[k][r]);
        return f;
    };
    const Step row = invert(marginal, R, unit_interval(xi1) * marginal(R));
    // Row r's blended conditional CDF G(c) = Σ_k w_k (M_k(r+1) − M_k(r)) C_k,r(c).
    std::array<double, 3> mass{};
    std::array<const float*, 3> conditional{};
    for (int k = 0; k < b.count; ++k) {
        const float* t = b.table[k];
        mass[k] = b.weight[k] * (double(t[row.index + 1]) - double(t[row.index]));
        conditional[k] = t + size_t(R + 1) * (row.index + 1);
    }
    const auto column_cdf = [&](int c) {
        double g = 0;
        for (int k = 0; k < b.count; ++k) g += mass[k] * double(conditional[k][c]);
        return g;
    };
    const Step col = invert(column_cdf, R, unit_interval(xi2) * column_cdf(R));
    LightSample s;
    s.wi = square_to_hemisphere({(col.index + col.offset) / R, (row.index + row.offset) / R});
    s.pdf = blend_pdf(b, s.wi);
    return s;
}

LightSample LightSampler::sample(const Uv& uv, const Vec3& wo, double xi1, double xi2) const {
    LightSample s = draw(blend(uv, wo), xi1, xi2);
    s.value = m_material.eval(uv, s.wi, wo);
    if (s.pdf > 0) s.weight = s.value * static_cast<float>(1 / s.pdf);
    return s;
}

LightSampler::Blend LightSampler::one_view(int x, int y, int view) const {
    check(x >= 0 && y >= 0 && x < m_material.width() && y < m_material.height() && view >= 0 &&
              view < m_views,
          "light sampler: texel ({}, {}) or view {} is outside the material", x, y, view);
    Blend b;
    b.table[0] = table((y / m_tile) * m_tiles_x + x / m_tile, view);
    b.weight[0] = b.total = 1;
    b.count = 1;
    return b;
}

LightSample LightSampler::sample_view(int x, int y, int view, double xi1, double xi2) const {
    return draw(one_view(x, y, view), xi1, xi2);
}

double LightSampler::pdf_view(int x, int y, int view, const Vec3& wi) const {
    if (!(wi.z >= 0)) return 0;
    return blend_pdf(one_view(x, y, view), wi);
}

double LightSampler::pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const {
    if (!(wi.z >= 0)) return 0;
    return blend_pdf(blend(uv, wo), wi);
}

Rgb quadrature_albedo(const Material& material, const Uv& uv, const Vec3& wo, int resolution) {
    check(resolution >= 1 && resolution <= 1024,
          "albedo: quadrature resolution {} out of range [1, 1024]", resolution);
    const std::vector<Vec3> centres = cell_centres(resolution);
    std::vector<Query> queries(centres.size());
    for (size_t i = 0; i < centres.size(); ++i) queries[i] = {uv, centres[i], wo};
    std::vector<Rgb> values(queries.size());
    material.eval_batch(queries, values);
    double r = 0, g = 0, b = 0;
    for (const Rgb& v : values) r += v.r, g += v.g, b += v.b;
    // (1/π) Σ value · 2π / n² = (2 / n²) Σ value.
    const double scale = 2.0 / (double(resolution) * resolution);
    return {static_cast<float>(r * scale), static_cast<float>(g * scale),
            static_cast<float>(b * scale)};
}

}  // namespace btf
