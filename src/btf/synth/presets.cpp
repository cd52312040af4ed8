// SPDX-License-Identifier: MIT
// The presets of the synthesizer: each is a function of a continuous position (u, v) on the
// unit square that returns the height and material parameters there. Heights are in units of
// the patch width, so a preset looks the same at every size (a 64² render is a coarser sampling
// of the 256² one), and every pattern has an integer number of periods across the patch, so it
// tiles.

#include <algorithm>
#include <cmath>
#include <functional>

#include "btf/synth/synth.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::synth {
namespace {

/// Material parameters at one point, as a preset returns them.
struct Point {
    double height = 0;  // patch-width units
    Rgb albedo;
    Rgb specular{0.04f, 0.04f, 0.04f};
    Rgb sheen;
    float alpha_t = 0.5f, alpha_b = 0.5f;
    float tangent = 0;          // radians from +u
    double coat_height = 0;     // patch-width units
    bool metal_bounce = false;  // bounce light off the specular reflectance, not the albedo
};

struct Globals {
    bool sheen = false;
    float sheen_roughness = 0.5f;
    bool coat = false;
    float coat_alpha = 0.05f, coat_f0 = 0.04f;
    double light_size_deg = 3.0;
    double bounce_radius = 0.01;  // patch-width units
};

using PointFn = std::function<Point(double u, double v)>;

struct Preset {
    PresetInfo info;
    Globals globals;
    std::function<PointFn(uint64_t seed)> make;
};

double smoothstep(double e0, double e1, double x) {
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3 - 2 * t);
}
Rgb mix(const Rgb& a, const Rgb& b, double t) {
    const float s = float(t);
    return {a.r + s * (b.r - a.r), a.g + s * (b.g - a.g), a.b + s * (b.b - a.b)};
}
Rgb scale(const Rgb& a, double s) {
    return a * float(s);
}
Rgb grey(double v) {
    return {float(v), float(v), float(v)};
}
double frac(double x) {
    return x - std::floor(x);
}

/// Half-circle profile of a round thread or yarn: 1 on its axis, 0 at distance `radius`.
double round_profile(double distance, double radius) {
    const double t = distance / radius;
    return t >= 1 ? 0.0 : std::sqrt(1 - t * t);
}

/// Distance from p to the segment ab, and the parameter of the closest point along it.
double segment_distance(double px, double py, double ax, double ay, double bx, double by,
                        double* t_out) {
    const double vx = bx - ax, vy = by - ay;
    const double t = std::clamp(((px - ax) * vx + (py - ay) * vy) / (vx * vx + vy * vy), 0.0, 1.0);
    *t_out = t;
    return std::hypot(px - ax - t * vx, py - ay - t * vy);
}

// ---- woven fabric: 2/2 twill of round threads, coloured warp and weft ----

PointFn woven_fabric(uint64_t seed) {
    return [seed](double u, double v) {
        constexpr int kThreads = 24;  // per patch, in each direction
        constexpr double kCell = 1.0 / kThreads;
        constexpr double kRadius = 0.46;  // thread half-width, in cells
        constexpr double kLift = 0.22;    // over/under excursion, in cells
        const double x = u * kThreads, y = v * kThreads;
        const int i = int(std::floor(x)), j = int(std::floor(y));
        const double fx = x - i, fy = y - j;
        auto warp_over = [](int a, int b) {
            return wrap_index(a + b, 4) < 2;  // twill: the over cells step diagonally
        };
        // Each thread's centre line rises over the crossings where it is on top and dips under
        // the others, interpolated with a cosine between crossing centres.
        auto undulation = [&](double along, int thread, bool is_warp) {
            const double s = along - 0.5;
            const int k0 = int(std::floor(s));
            const double t = s - k0;
            auto state = [&](int k) {
                const int kw = wrap_index(k, kThreads), tw = wrap_index(thread, kThreads);
                const bool over = is_warp ? warp_over(tw, kw) : !warp_over(kw, tw);
                return over ? 1.0 : -1.0;
            };
            const double w = 0.5 - 0.5 * std::cos(kPi * t);
            return state(k0) + w * (state(k0 + 1) - state(k0));
        };
        const int wi = wrap_index(i, kThreads), wj = wrap_index(j, kThreads);
        // Ply twist: diagonal stripes along each thread.
        const double twist_warp = std::sin(2 * kPi * (3 * y + 1.4 * fx));
        const double twist_weft = std::sin(2 * kPi * (3 * x + 1.4 * fy));
        const double warp = kRadius * round_profile(std::abs(fx - 0.5), kRadius) +
                            kLift * undulation(y, wi, true) + 0.03 * twist_warp;
        const double weft = kRadius * round_profile(std::abs(fy - 0.5), kRadius) +
                            kLift * undulation(x, wj, false) + 0.03 * twist_weft;
        const bool warp_top = warp >= weft;
        Point p;
        p.height = std::max({warp, weft, -kLift - 0.1}) * kCell;
        const double fibre = 0.5 + 0.5 * (warp_top ? twist_warp : twist_weft);
        if (warp_top) {
            const double vary = 0.85 + 0.3 * hash_unit(seed, wi, 11);
            p.albedo = scale(Rgb{0.42f, 0.07f, 0.06f}, vary * (0.85 + 0.25 * fibre));
            p.tangent = float(kPi / 2);
        } else {
            const double vary = 0.9 + 0.2 * hash_unit(seed, wj, 12);
            p.albedo = scale(Rgb{0.62f, 0.52f, 0.34f}, vary * (0.85 + 0.25 * fibre));
            p.tangent = 0;
        }
        // Threads in the gaps between crossings sit deep and are seen through dust and fuzz.
        const double depth = smoothstep(-kLift - 0.1, kLift, std::max(warp, weft));
        p.albedo = scale(p.albedo, 0.55 + 0.45 * depth);
        p.specular = grey(0.04);
        p.alpha_t = 0.18f, p.alpha_b = 0.45f;
        p.sheen = scale(mix(p.albedo, grey(0.5), 0.5), 0.6);
        return p;
    };
}

// ---- embroidered linen: plain-weave ground with raised, glossy satin-stitch motifs ----

PointFn embroidered_linen(uint64_t seed) {
    return [seed](double u, double v) {
        constexpr int kThreads = 40;
        constexpr double kCell = 1.0 / kThreads;
        const double x = u * kThreads, y = v * kThreads;
        const int i = int(std::floor(x)), j = int(std::floor(y));
        const double fx = x - i, fy = y - j;
        const int wi = wrap_index(i, kThreads), wj = wrap_index(j, kThreads);
        // Plain weave: warp and weft alternate over and under at every crossing.
        const bool warp_over = wrap_index(wi + wj, 2) == 0;
        const double lift = 0.15;
        const double slub_warp = 0.08 * noise(u, v, kThreads, 3, seed + 1);  // uneven yarn
        const double slub_weft = 0.08 * noise(u, v, 3, kThreads, seed + 2);
        const double warp =
            (0.42 + slub_warp) * round_profile(std::abs(fx - 0.5), 0.42 + slub_warp) +
            (warp_over ? lift : -lift) * std::sin(kPi * fy);
        const double weft =
            (0.42 + slub_weft) * round_profile(std::abs(fy - 0.5), 0.42 + slub_weft) +
            (warp_over ? -lift : lift) * std::sin(kPi * fx);
        const bool warp_top = warp >= weft;
        const double ground = std::max({warp, weft, -0.2}) * kCell;
        const double linen_tone = 0.9 + 0.1 * (warp_top ? slub_warp : slub_weft) / 0.08;

        // Motifs: blobs of a thresholded smooth noise, filled with satin stitches at 40°.
        const double field = fbm(u, v, 3, 3, 3, 0.45, seed + 3);
        const double motif = smoothstep(0.12, 0.16, field);
        // Stitch lines run along (43, 36), about 40° from u: integer wave numbers keep them
        // continuous across the patch edges.
        const double beta = std::atan2(36.0, 43.0);
        const double across = -36 * u + 43 * v;
        const double fc = frac(across);
        const double stitch = round_profile(std::abs(fc - 0.5), 0.47);
        const double raised = motif * (0.5 + 0.5 * stitch) * 1.3 * kCell;

        Point p;
        if (raised > ground + 0.05 * kCell) {
            p.height = raised;
            const bool dark = fbm(u, v, 2, 2, 2, 0.5, seed + 4) > 0.1;
            const Rgb silk = dark ? Rgb{0.30f, 0.05f, 0.18f} : Rgb{0.70f, 0.34f, 0.52f};
            p.albedo = scale(silk, 0.8 + 0.2 * stitch);
            p.tangent = float(beta);
            p.alpha_t = 0.12f, p.alpha_b = 0.35f;
            p.specular = grey(0.05);
            p.sheen = scale(silk, 0.5);
        } else {
            p.height = ground;
            const Rgb linen{0.66f, 0.62f, 0.48f};
            const double depth = smoothstep(-0.2, 0.4, std::max(warp, weft));
            p.albedo = scale(linen, linen_tone * (0.6 + 0.4 * depth));
            p.tangent = warp_top ? float(kPi / 2) : 0.0f;
            p.alpha_t = 0.3f, p.alpha_b = 0.6f;
            p.specular = grey(0.04);
            p.sheen = scale(linen, 0.3);
        }
        return p;
    };
}

// ---- knitted wool: stockinette V loops of thick, fuzzy, heathered yarn ----

PointFn knitted_wool(uint64_t seed) {
    return [seed](double u, double v) {
        constexpr int kCols = 10, kRows = 14;
        constexpr double kW = 1.0 / kCols, kH = 1.0 / kRows;
        constexpr double kYarn = 0.26 * kW;  // yarn radius (patch units)
        const double x = u * kCols, y = v * kRows;
        const int ci = int(std::floor(x)), cj = int(std::floor(y));
        double best = -1e9, best_tangent = 0, best_shade = 0;
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                const int a = ci + di, b = cj + dj;
                // The two legs of the V of stitch (a, b), in patch units.
                for (int leg = 0; leg < 2; ++leg) {
                    const double x0 = (a + (leg == 0 ? 0.06 : 0.94)) * kW;
                    const double x1 = (a + (leg == 0 ? 0.47 : 0.53)) * kW;
                    const double y0 = (b - 0.15) * kH, y1 = (b + 1.05) * kH;
                    double t;
                    const double d = segment_distance(u, v, x0, y0, x1, y1, &t);
                    if (d >= kYarn) continue;
                    // A leg bulges up in its middle and tucks under the row above at its ends.
                    const double h = kYarn * round_profile(d, kYarn) +
                                     0.45 * kYarn * std::sin(kPi * t) - 0.3 * kYarn;
                    if (h > best) {
                        best = h;
                        best_tangent = std::atan2(y1 - y0, x1 - x0);
                        best_shade = t;
                    }
                }
            }
        Point p;
        const double floor_h = -0.55 * kYarn;
        const bool on_yarn = best > floor_h;
        const double fuzz = fbm(u, v, 64, 64, 2, 0.5, seed + 1);
        p.height = std::max(best, floor_h) + 0.05 * kYarn * fuzz;
        // Heathered yarn: two close greys mixed by a fine fibre noise, with rare light flecks.
        const double fibres = fbm(u, v, 48, 96, 3, 0.6, seed + 2);
        Rgb wool = mix(Rgb{0.30f, 0.33f, 0.38f}, Rgb{0.42f, 0.42f, 0.43f}, 0.5 + 0.8 * fibres);
        const int fleck_x = wrap_index(int(std::floor(u * 300)), 300);
        const int fleck_y = wrap_index(int(std::floor(v * 300)), 300);
        if (hash_unit(seed + 3, fleck_x, fleck_y) < 0.02) wool = scale(wool, 1.35);
        const double ply = 0.9 + 0.1 * std::sin(2 * kPi * (best_shade * 3 + x * 0.5));
        p.albedo = on_yarn ? scale(wool, ply) : scale(wool, 0.55);
        p.tangent = float(best_tangent);
        p.specular = grey(0.035);
        p.alpha_t = 0.55f, p.alpha_b = 0.85f;
        p.sheen = scale(wool, 1.2);
        return p;
    };
}

// ---- leather: cellular pebble grain with creases, pores and a medium-gloss finish ----

PointFn leather(uint64_t seed) {
    return [seed](double u, double v) {
        const Cells cells = worley(u, v, 16, 0.9, seed + 1);
        const double edge = cells.f2 - cells.f1;  // ≈ 0 on a crease, larger inside a pebble
        const double pebble = std::pow(smoothstep(0.0, 0.45, edge), 0.6);
        const double pebble_h = 0.35 + 0.65 * double(cells.id % 1000) / 1000.0;
        const Cells pores = worley(u, v, 96, 1.0, seed + 2);
        const double pore = 1 - smoothstep(0.08, 0.22, pores.f1);
        const double wrinkle = fbm(u, v, 3, 3, 3, 0.5, seed + 3);
        Point p;
        p.height = 0.010 * pebble * (0.7 + 0.3 * pebble_h) - 0.0012 * pore + 0.004 * wrinkle;
        const double tone = 0.85 + 0.3 * fbm(u, v, 6, 6, 3, 0.55, seed + 4);
        Rgb base = scale(Rgb{0.20f, 0.085f, 0.04f}, tone);
        base = scale(base, 0.55 + 0.45 * pebble);  // creases hold dark dye
        base = mix(base, Rgb{0.30f, 0.15f, 0.08f}, 0.25 * smoothstep(0.3, 0.6, edge));  // wear
        p.albedo = scale(base, 1 - 0.35 * pore);
        p.specular = grey(0.045);
        const float a = float(0.28 + 0.3 * (1 - pebble) + 0.1 * pore);
        p.alpha_t = p.alpha_b = a;
        return p;
    };
}

// ---- ceramic tiles: glossy glazed tiles in a grid with deep, rough grout grooves ----

PointFn ceramic_tiles(uint64_t seed) {
    return [seed](double u, double v) {
        constexpr int kTiles = 4;
        constexpr double kTile = 1.0 / kTiles;
        constexpr double kGroove = 0.014;  // half-width of the grout joint (patch units)
        constexpr double kBevel = 0.009;   // radius of the rounded tile edge
        constexpr double kDepth = 0.03;    // grout surface below the tile top
        const double x = u * kTiles, y = v * kTiles;
        const int i = int(std::floor(x)), j = int(std::floor(y));
        const double fx = x - i, fy = y - j;
        const double dx = std::min(fx, 1 - fx) * kTile, dy = std::min(fy, 1 - fy) * kTile;
        const double dist = std::min(dx, dy);  // to the nearest joint centre line
        const int ti = wrap_index(i, kTiles), tj = wrap_index(j, kTiles);
        Point p;
        if (dist < kGroove) {
            // Grout: sandy, rough, slightly concave.
            const double sand = fbm(u, v, 64, 64, 2, 0.5, seed + 5);
            p.height = -kDepth + 0.002 * sand + 0.003 * (dist / kGroove);
            p.albedo = scale(Rgb{0.38f, 0.36f, 0.33f}, 0.9 + 0.25 * sand);
            p.specular = grey(0.03);
            p.alpha_t = p.alpha_b = 0.85f;
            return p;
        }
        // Tile: rounded edge, a small random tilt and a gentle wave in the glaze, so that
        // highlights land on different tiles for neighbouring light directions.
        const double e = dist - kGroove;
        const double bevel =
            e < kBevel
                ? -kBevel + std::sqrt(std::max(0.0, kBevel * kBevel - (kBevel - e) * (kBevel - e)))
                : 0.0;
        const double wall = e < 0.0015 ? -kDepth * (1 - e / 0.0015) : 0.0;
        const double tilt_x = 0.02 * (hash_unit(seed, ti, tj, 1) - 0.5);
        const double tilt_y = 0.02 * (hash_unit(seed, ti, tj, 2) - 0.5);
        const double wave = fbm(u, v, 8, 8, 3, 0.5, seed + 6);
        p.height = std::min(bevel, 0.0) + std::min(wall, 0.0) + tilt_x * (fx - 0.5) * kTile +
                   tilt_y * (fy - 0.5) * kTile + 0.0012 * wave;
        // Glaze colour: per-tile shade of one of two glazes, pooling darker near the edges.
        const bool blue = hash_unit(seed, ti, tj, 3) < 0.5;
        Rgb glaze = blue ? Rgb{0.05f, 0.20f, 0.32f} : Rgb{0.62f, 0.58f, 0.50f};
        glaze = scale(glaze, 0.85 + 0.3 * hash_unit(seed, ti, tj, 4));
        const double mottling = fbm(u, v, 16, 16, 3, 0.5, seed + 7);
        glaze = scale(glaze, (0.9 + 0.2 * mottling) * (0.75 + 0.25 * smoothstep(0, kBevel, e)));
        p.albedo = glaze;
        p.specular = grey(0.045);
        p.alpha_t = p.alpha_b = float(0.07 + 0.05 * (1 - smoothstep(0, kBevel, e)));
        return p;
    };
}

// ---- brushed metal: aluminium tread plate with raised lozenges, brushed along u ----

PointFn brushed_metal(uint64_t seed) {
    return [seed](double u, double v) {
        constexpr int kCells = 8;
        constexpr double kHeight = 0.012;
        constexpr double kHalfLength = 0.34, kHalfWidth = 0.085;  // in cells
        const double x = u * kCells, y = v * kCells;
        const int ci = int(std::floor(x)), cj = int(std::floor(y));
        double lozenge = 0;
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                const int a = ci + di, b = cj + dj;
                // Diamond-plate pattern: lozenges alternate between +45° and −45°.
                const double angle = (wrap_index(a + b, 2) == 0 ? 1 : -1) * kPi / 4;
                const double ca = std::cos(angle), sa = std::sin(angle);
                const double px = x - (a + 0.5), py = y - (b + 0.5);
                const double along = (px * ca + py * sa) / kHalfLength;
                const double across = (-px * sa + py * ca) / kHalfWidth;
                // Superellipse: flat-topped with rounded flanks.
                const double r = std::pow(
                    std::pow(std::abs(along), 2.5) + std::pow(std::abs(across), 2.5), 1 / 2.5);
                lozenge = std::max(
                    lozenge, std::sqrt(std::max(0.0, 1 - r * r)) * (1 - 0.35 * along * along));
            }
        const double shape = std::min(1.0, 1.6 * lozenge);
        const double scratches =
            noise(u, v, 3, 160, seed + 1) + 0.5 * noise(u, v, 6, 320, seed + 2);
        const double dents = fbm(u, v, 5, 5, 3, 0.5, seed + 3);
        Point p;
        p.height = kHeight * shape + 0.00012 * scratches + 0.0006 * dents;
        // Darker oxide in the corners where the lozenges meet the plate.
        const double corner = shape > 0.02 && shape < 0.5 ? 0.8 : 1.0;
        const double sheen = (0.93 + 0.05 * scratches) * corner;
        p.specular = scale(Rgb{0.91f, 0.92f, 0.92f}, sheen);
        p.albedo = grey(0.015);
        p.alpha_t = 0.07f, p.alpha_b = 0.30f;
        p.tangent = 0;  // brushed along u, on the lozenges too
        p.metal_bounce = true;
        return p;
    };
}

// ---- lacquered wood: flat-sawn grain with open pores under a glossy clear coat ----

PointFn lacquered_wood(uint64_t seed) {
    return [seed](double u, double v) {
        constexpr int kRings = 12;
        const double warp = fbm(u, v, 2, 3, 3, 0.5, seed + 1);
        const double ring = frac(kRings * v + 0.9 * warp + 0.25 * std::sin(2 * kPi * u) +
                                 0.04 * noise(u, v, 6, 24, seed + 6));
        const double late = smoothstep(0.55, 0.8, ring) * (1 - smoothstep(0.92, 1.0, ring));
        const double streak = noise(u, v, 4, 96, seed + 2) + 0.5 * noise(u, v, 8, 192, seed + 3);
        const double pore_noise = noise(u, v, 24, 150, seed + 4);
        const double pore = smoothstep(0.45, 0.75, pore_noise) * (1 - 0.6 * late);
        Point p;
        // Brushed ("structured") finish: the soft earlywood is worn back, so latewood bands stand
        // proud and the open pores are deep grooves along the grain.
        const double relief = 0.005 * late + 0.0003 * streak;
        p.height = relief - 0.008 * pore;
        Rgb early{0.50f, 0.28f, 0.13f}, latewood{0.26f, 0.12f, 0.05f};
        Rgb wood = mix(early, latewood, late);
        wood = scale(wood, (0.9 + 0.12 * streak) * (1 - 0.6 * pore));
        p.albedo = wood;
        p.specular = grey(0.04);
        p.alpha_t = 0.3f, p.alpha_b = 0.5f;
        p.tangent = 0;
        // The lacquer follows the relief, softened, with a faint orange peel of its own.
        // Pores are mostly bridged by the lacquer.
        p.coat_height = 0.7 * relief - 0.001 * pore + 0.0008 * fbm(u, v, 12, 12, 2, 0.5, seed + 5);
        return p;
    };
}

const std::vector<Preset>& registry() {
    static const std::vector<Preset> list = [] {
        std::vector<Preset> presets;
        Globals fabric;
        fabric.sheen = true, fabric.sheen_roughness = 0.4f;
        fabric.bounce_radius = 0.008;
        presets.push_back({{"woven_fabric",
                            "2/2 twill of round red warp and beige weft threads: interlacing, "
                            "deep pits, anisotropic fibre highlights and sheen"},
                           fabric,
                           woven_fabric});
        Globals linen;
        linen.sheen = true, linen.sheen_roughness = 0.5f;
        linen.bounce_radius = 0.008;
        presets.push_back({{"embroidered_linen",
                            "plain-weave linen with raised glossy satin-stitch motifs in two "
                            "pinks, like the measured UBO2003 sample"},
                           linen,
                           embroidered_linen});
        Globals wool;
        wool.sheen = true, wool.sheen_roughness = 0.7f;
        wool.light_size_deg = 4.0;
        wool.bounce_radius = 0.012;
        presets.push_back({{"knitted_wool",
                            "stockinette V loops of thick heathered grey wool: deep crevices, "
                            "fuzzy, rough, low contrast"},
                           wool,
                           knitted_wool});
        presets.push_back({{"leather",
                            "dark brown pebble-grain leather: cellular grain, dark creases, "
                            "pores, medium gloss"},
                           Globals{},
                           leather});
        Globals tiles;
        tiles.bounce_radius = 0.015;
        presets.push_back({{"ceramic_tiles",
                            "4×4 glossy glazed tiles (blue and cream) with deep rough grout "
                            "grooves that cast long shadows"},
                           tiles,
                           ceramic_tiles});
        Globals metal;
        metal.light_size_deg = 2.0;
        presets.push_back({{"brushed_metal",
                            "brushed aluminium tread plate: raised lozenges, anisotropic "
                            "highlight stretched across the brushing"},
                           metal,
                           brushed_metal});
        Globals wood;
        wood.coat = true, wood.coat_alpha = 0.06f, wood.coat_f0 = 0.045f;
        presets.push_back(
            {{"lacquered_wood", "flat-sawn wood grain with open pores under a glossy clear coat"},
             wood,
             lacquered_wood});
        return presets;
    }();
    return list;
}

}  // namespace

const std::vector<PresetInfo>& presets() {
    static const std::vector<PresetInfo> infos = [] {
        std::vector<PresetInfo> out;
        for (const Preset& p : registry()) out.push_back(p.info);
        return out;
    }();
    return infos;
}

std::vector<std::string> preset_names() {
    std::vector<std::string> names;
    for (const PresetInfo& p : presets()) names.push_back(p.name);
    return names;
}

namespace {

const Preset& find_preset(const std::string& name) {
    for (const Preset& p : registry())
        if (p.info.name == name) return p;
    std::string names;
    for (const PresetInfo& p : presets()) names += (names.empty() ? "" : ", ") + p.name;
    fail("synthetic BTF: unknown preset '{}' (valid presets: {})", name, names);
}

// Each preset draws from its own stream, keyed by its name (not its position in the list, so
// adding a preset changes no other).
PointFn point_function(const Preset& preset, uint64_t seed) {
    uint64_t key = 0x5eed;
    for (unsigned char c : preset.info.name) key = mix64(key ^ c);
    return preset.make(hash(seed, int64_t(key)));
}

}  // namespace

PresetSample sample_preset(const std::string& preset, uint64_t seed, double u, double v) {
    const Point p = point_function(find_preset(preset), seed)(u, v);
    return {p.height, p.albedo};
}

Surface make_surface(const std::string& preset, int size, uint64_t seed) {
    const Preset* found = &find_preset(preset);
    check(size >= kMinSize && size <= kMaxSize,
          "synthetic BTF '{}': size {} is outside [{}, {}] texels", preset, size, kMinSize,
          kMaxSize);
    const PointFn fn = point_function(*found, seed);
    const Globals& g = found->globals;

    Surface s;
    s.size = size;
    const size_t count = size_t(size) * size;
    s.height = Field(size);
    s.coat_height = g.coat ? Field(size) : Field();
    s.albedo.resize(count);
    s.specular.resize(count);
    s.bounce.resize(count);
    if (g.sheen) s.sheen.resize(count);
    s.alpha_t.resize(count);
    s.alpha_b.resize(count);
    s.tangent.resize(count);
    parallel_chunks(0, size, 4, [&](int64_t y0, int64_t y1) {
        for (int y = int(y0); y < int(y1); ++y)
            for (int x = 0; x < size; ++x) {
                const Point p = fn((x + 0.5) / size, (y + 0.5) / size);
                const size_t i = size_t(y) * size + x;
                s.height(x, y) = float(p.height * size);
                if (g.coat) s.coat_height(x, y) = float(p.coat_height * size);
                s.albedo[i] = p.albedo;
                s.specular[i] = p.specular;
                // Light bounced off neighbouring surfaces reaches a texel as diffuse light;
                // metals pass on a part of their (specular) reflectance.
                s.bounce[i] = p.metal_bounce ? scale(p.specular, 0.25) : p.albedo;
                if (g.sheen) s.sheen[i] = p.sheen;
                s.alpha_t[i] = p.alpha_t;
                s.alpha_b[i] = p.alpha_b;
                s.tangent[i] = p.tangent;
            }
    });
    s.reference = s.height.mean();
    s.sheen_roughness = g.sheen_roughness;
    s.coat = g.coat;
    s.coat_alpha = g.coat_alpha;
    s.coat_f0 = g.coat_f0;
    s.light_size = radians(g.light_size_deg);
    s.bounce_radius = std::max(1, int(std::lround(g.bounce_radius * size)));
    return s;
}

}  // namespace btf::synth
