// SPDX-License-Identifier: MIT
#include "btf/synth/heightfield.h"

#include <algorithm>
#include <cmath>

#include "btf/util/parallel.h"

namespace btf::synth {

uint64_t mix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

uint64_t hash(uint64_t seed, int64_t a, int64_t b, int64_t c) {
    uint64_t h = mix64(seed);
    h = mix64(h ^ uint64_t(a));
    h = mix64(h ^ uint64_t(b));
    return mix64(h ^ uint64_t(c));
}

double hash_unit(uint64_t seed, int64_t a, int64_t b, int64_t c) {
    return double(hash(seed, a, b, c) >> 11) * 0x1.0p-53;
}

// ---- Field ----

Field::Field(int size, float fill) : m_size(size), m_values(size_t(size) * size, fill) {}

float Field::wrapped(int x, int y) const {
    return (*this)(wrap_index(x, m_size), wrap_index(y, m_size));
}

float Field::bilinear(double x, double y) const {
    const double fx = x - 0.5, fy = y - 0.5;
    const double x0f = std::floor(fx), y0f = std::floor(fy);
    const float tx = float(fx - x0f), ty = float(fy - y0f);
    const int x0 = wrap_index(int(x0f), m_size), y0 = wrap_index(int(y0f), m_size);
    const int x1 = x0 + 1 == m_size ? 0 : x0 + 1, y1 = y0 + 1 == m_size ? 0 : y0 + 1;
    const float* r0 = &m_values[size_t(y0) * m_size];
    const float* r1 = &m_values[size_t(y1) * m_size];
    const float a = r0[x0] + tx * (r0[x1] - r0[x0]);
    const float b = r1[x0] + tx * (r1[x1] - r1[x0]);
    return a + ty * (b - a);
}

float Field::min() const {
    return *std::min_element(m_values.begin(), m_values.end());
}
float Field::max() const {
    return *std::max_element(m_values.begin(), m_values.end());
}
double Field::mean() const {
    double sum = 0;
    for (float v : m_values) sum += v;
    return m_values.empty() ? 0.0 : sum / double(m_values.size());
}

// ---- noise ----

namespace {

double fade(double t) {
    return t * t * t * (t * (t * 6 - 15) + 10);
}

double gradient_dot(uint64_t seed, int i, int j, double dx, double dy) {
    const double angle = 2 * kPi * hash_unit(seed, i, j);
    return std::cos(angle) * dx + std::sin(angle) * dy;
}

}  // namespace

double noise(double u, double v, int px, int py, uint64_t seed) {
    const double x = u * px, y = v * py;
    const double xf = std::floor(x), yf = std::floor(y);
    const double dx = x - xf, dy = y - yf;
    const int i0 = wrap_index(int(xf), px), j0 = wrap_index(int(yf), py);
    const int i1 = i0 + 1 == px ? 0 : i0 + 1, j1 = j0 + 1 == py ? 0 : j0 + 1;
    const double n00 = gradient_dot(seed, i0, j0, dx, dy);
    const double n10 = gradient_dot(seed, i1, j0, dx - 1, dy);
    const double n01 = gradient_dot(seed, i0, j1, dx, dy - 1);
    const double n11 = gradient_dot(seed, i1, j1, dx - 1, dy - 1);
    const double sx = fade(dx), sy = fade(dy);
    const double a = n00 + sx * (n10 - n00), b = n01 + sx * (n11 - n01);
    // 2-D gradient noise peaks at ±√½; scale to about ±1.
    return std::sqrt(2.0) * (a + sy * (b - a));
}

double fbm(double u, double v, int px, int py, int octaves, double gain, uint64_t seed) {
    double sum = 0, amplitude = 1, norm = 0;
    for (int k = 0; k < octaves; ++k) {
        sum += amplitude * noise(u, v, px << k, py << k, mix64(seed + uint64_t(k)));
        norm += amplitude;
        amplitude *= gain;
    }
    return sum / norm;
}

Cells worley(double u, double v, int cells, double jitter, uint64_t seed) {
    const double x = u * cells, y = v * cells;
    const int cx = int(std::floor(x)), cy = int(std::floor(y));
    Cells result;
    result.f1 = result.f2 = 1e30;
    for (int dj = -2; dj <= 2; ++dj)
        for (int di = -2; di <= 2; ++di) {
            const int i = cx + di, j = cy + dj;
            const int wi = wrap_index(i, cells), wj = wrap_index(j, cells);
            const double px = i + 0.5 + jitter * (hash_unit(seed, wi, wj, 1) - 0.5);
            const double py = j + 0.5 + jitter * (hash_unit(seed, wi, wj, 2) - 0.5);
            const double d = std::hypot(px - x, py - y);
            if (d < result.f1) {
                result.f2 = result.f1;
                result.f1 = d;
                result.ix = wi, result.iy = wj;
            } else if (d < result.f2) {
                result.f2 = d;
            }
        }
    result.id = hash(seed, result.ix, result.iy, 3);
    return result;
}

// ---- filters ----

Field blur(const Field& field, int radius, int passes) {
    const int n = field.size();
    radius = std::clamp(radius, 0, (n - 1) / 2);
    if (radius == 0 || passes <= 0) return field;
    Field a = field, b(n);
    const float scale = 1.0f / float(2 * radius + 1);
    for (int pass = 0; pass < passes; ++pass) {
        // Horizontal then vertical running sums, wrapped; double sums keep the drift away.
        for (int y = 0; y < n; ++y) {
            double sum = 0;
            for (int k = -radius; k <= radius; ++k) sum += a.wrapped(k, y);
            for (int x = 0; x < n; ++x) {
                b(x, y) = float(sum) * scale;
                sum += a.wrapped(x + radius + 1, y) - a.wrapped(x - radius, y);
            }
        }
        for (int x = 0; x < n; ++x) {
            double sum = 0;
            for (int k = -radius; k <= radius; ++k) sum += b.wrapped(x, k);
            for (int y = 0; y < n; ++y) {
                a(x, y) = float(sum) * scale;
                sum += b.wrapped(x, y + radius + 1) - b.wrapped(x, y - radius);
            }
        }
    }
    return a;
}

// ---- ray queries ----

void light_visibility(const Field& height, const Vec3& light, double light_size, float* out) {
    const int n = height.size();
    const double horizontal = std::hypot(light.x, light.y);
    if (horizontal < 1e-9 || light.z <= 0) {
        // Straight overhead (nothing can block it) or below the horizon (the local cosine is
        // zero for every texel anyway).
        std::fill(out, out + size_t(n) * n, light.z > 0 ? 1.0f : 0.0f);
        return;
    }
    const double dx = light.x / horizontal, dy = light.y / horizontal;
    const double elevation = std::atan2(light.z, horizontal);
    const double half = 0.5 * std::max(light_size, 1e-4);
    // Occluders seen below this slope cannot dim the light at all.
    const double free_slope = std::tan(std::max(elevation - half, 1e-3));
    const double top = height.max();
    constexpr double kStep = 0.5;  // texels: finer than the height field's sampling
    parallel_chunks(0, n, 4, [&](int64_t y0, int64_t y1) {
        for (int y = int(y0); y < int(y1); ++y)
            for (int x = 0; x < n; ++x) {
                const double h0 = height(x, y);
                const double cx = x + 0.5, cy = y + 0.5;
                double max_slope = -1e30;
                // Start one texel away: the immediate neighbourhood is the local slope, which the
                // shading cosine already accounts for.
                for (double s = 1.0; s <= n; s += kStep) {
                    const double bound = (top - h0) / s;
                    if (bound <= std::max(max_slope, free_slope)) break;
                    const double slope = (height.bilinear(cx + s * dx, cy + s * dy) - h0) / s;
                    max_slope = std::max(max_slope, slope);
                }
                const double margin = elevation - std::atan(max_slope);
                out[size_t(y) * n + x] = float(std::clamp(0.5 + margin / (2 * half), 0.0, 1.0));
            }
    });
}

void view_hits(const Field& height, const Vec3& view, double reference, float* hit_x,
               float* hit_y) {
    const int n = height.size();
    const double horizontal = std::hypot(view.x, view.y);
    const double top = height.max(), bottom = height.min();
    const bool overhead = horizontal < 1e-9 || view.z <= 0;
    const bool flat = top - bottom < 1e-9;
    // Parameter t runs along the ray from the viewer's side: point = centre + t·view.
    const double t_top = (top - reference) / std::max(view.z, 1e-6);
    const double t_bottom = (bottom - reference) / std::max(view.z, 1e-6);
    const double dt = 0.5 / std::max(horizontal, 1e-9);  // half a texel horizontally per step
    parallel_chunks(0, n, 4, [&](int64_t y0, int64_t y1) {
        for (int y = int(y0); y < int(y1); ++y)
            for (int x = 0; x < n; ++x) {
                const double cx = x + 0.5, cy = y + 0.5;
                const size_t i = size_t(y) * n + x;
                if (overhead || flat) {
                    const double t = overhead ? 0.0 : t_top;
                    hit_x[i] = float(cx + t * view.x), hit_y[i] = float(cy + t * view.y);
                    continue;
                }
                auto gap = [&](double t) {  // ray height above the surface
                    return reference + t * view.z -
                           height.bilinear(cx + t * view.x, cy + t * view.y);
                };
                double t_prev = t_top, g_prev = gap(t_top);
                double t_hit = t_bottom;
                if (g_prev <= 0) {
                    t_hit = t_top;
                } else {
                    for (double t = t_top - dt;; t -= dt) {
                        if (t < t_bottom) t = t_bottom;
                        const double g = gap(t);
                        if (g <= 0) {
                            // Secant refinement inside the bracketing step [t, t_prev].
                            double lo = t, hi = t_prev, g_lo = g, g_hi = g_prev;
                            for (int k = 0; k < 4; ++k) {
                                const double tm = lo + (hi - lo) * g_lo / (g_lo - g_hi);
                                const double gm = gap(tm);
                                if (gm <= 0)
                                    lo = tm, g_lo = gm;
                                else
                                    hi = tm, g_hi = gm;
                                if (hi - lo < 1e-3) break;
                            }
                            t_hit = g_lo == g_hi ? lo : lo + (hi - lo) * g_lo / (g_lo - g_hi);
                            break;
                        }
                        if (t <= t_bottom) break;
                        t_prev = t, g_prev = g;
                    }
                }
                hit_x[i] = float(cx + t_hit * view.x);
                hit_y[i] = float(cy + t_hit * view.y);
            }
    });
}

Field sky_visibility(const Field& height, int azimuths) {
    const int n = height.size();
    Field sky(n, 1.0f);
    const double top = height.max();
    parallel_chunks(0, n, 4, [&](int64_t y0, int64_t y1) {
        for (int y = int(y0); y < int(y1); ++y)
            for (int x = 0; x < n; ++x) {
                const double h0 = height(x, y);
                const double cx = x + 0.5, cy = y + 0.5;
                double open = 0;
                for (int a = 0; a < azimuths; ++a) {
                    const double phi = 2 * kPi * (a + 0.5) / azimuths;
                    const double dx = std::cos(phi), dy = std::sin(phi);
                    double max_slope = 0;
                    for (double s = 1.0; s <= 0.5 * n; s += std::max(0.5, 0.1 * s)) {
                        if ((top - h0) / s <= max_slope) break;
                        const double slope = (height.bilinear(cx + s * dx, cy + s * dy) - h0) / s;
                        max_slope = std::max(max_slope, slope);
                    }
                    // Projected solid angle above a horizon at elevation e is cos²e of the slice.
                    open += 1.0 / (1.0 + max_slope * max_slope);
                }
                sky(x, y) = float(open / azimuths);
            }
    });
    return sky;
}

}  // namespace btf::synth
