// SPDX-License-Identifier: MIT
#pragma once
/// The generic light-direction sampler and the quadrature albedo: the defaults of
/// Material::sample(), pdf() and albedo() for materials that cannot sample from their own
/// representation (fmf, pca-views, lpca, perceptual, UBO2014 files). A codec with native sampling
/// (mlvq, from its code-books) overrides them; this sampler stays the reference it is compared
/// with.
///
/// The problem: a path tracer that hits a BTF surface at (x, ωo) wants light directions ωi drawn
/// with a density p(ωi) roughly proportional to value(x, ωi, ωo), the function it integrates
/// (∫ L_i · value / π dωi, see material.h for the value convention). A generic sampler only has
/// eval(), so it tabulates that function on a grid of light directions and inverts its CDF.
///
/// Design:
/// - Grid over the light hemisphere: the area-preserving square↔hemisphere map of
///   btf/core/hemisphere.h with R × R cells over the square (R = `resolution`, default 32), so
///   every cell has the same solid angle 2π/R² (0.0061 sr, about 4.5° across at R = 32: three to
///   four cells per edge of the ≈ 15° triangles between the 81 UBO2003 light directions, finer
///   than the function the angular interpolator can represent).
/// - What is tabulated: per texel tile and per sampled view, the luminance (Rec. 709, clamped at
///   0) of the value at each cell's centre direction, averaged over k × k points of the tile
///   (k = `points_per_side`, default 4). Each point lies on a texel corner, where the material's
///   bilinear spatial interpolation averages the 2 × 2 texels around it, so 16 evaluations
///   average 64 of a 16 × 16 tile's 256 texels evenly spread over it (a stratified quarter of the
///   tile, not all of it: the whole tile would cost 16× more per table for a distribution that
///   only steers the samples and never biases them).
/// - Texel tiles rather than texel clusters: tiles need no clustering pass, work for every
///   material through eval() alone, and are found from uv in O(1). Per-texel tables (tile 1,
///   one point) are not better overall: their variance was 0.15–3.4× that of 16² tiles in the
///   measurements below (lower where a texel's lobe differs from its tile's, as on grout lines;
///   higher where one texel's value is a noisier guide than a tile average). Tile size
///   `tile_size` (default 16 × 16 texels); it is doubled until every table of the material fits
///   `memory_budget` (default 256 MiB), so memory is bounded by construction without eviction.
/// - Views: the table for ωo is the mixture of the tables of the ≤ 3 sampled views around ωo
///   with the barycentric weights of the shared AngularInterpolator over the view set, i.e. the
///   weights with which eval() blends those views' values. Since the material's value at ωo *is*
///   that blend of the views' values, the mixture follows it closely, while the table of the
///   nearest view alone puts its highlight where that view has it, up to half a view spacing
///   (×2 after reflection) away from where the blend has its lobes. Measured (variance of the
///   luminance of value / pdf over 20 000 draws, at 6 (uv, ωo) between the views, on fmf
///   materials of the 16² presets brushed_metal, lacquered_wood, ceramic_tiles, leather and
///   woven_fabric): with 14 views × 81 lights the nearest view's variance is 1.0–209× the
///   blend's and reaches 5.8× that of uniform hemisphere sampling (brushed_metal: blend
///   0.47–2.6, nearest 1.7–538, uniform 25–94); with all 81 UBO2003 views it is 0.84–67× the
///   blend's (below 1 only on the near-diffuse leather and woven_fabric). At a
///   sampled view both are the same table. The blend costs one AngularInterpolator lookup
///   instead of a nearest-view search, and three table reads per pdf(); sampling inverts the
///   blended CDFs directly (a binary search whose probes sum ≤ 3 table entries), so the map
///   ξ → ωi stays continuous instead of switching tables at component boundaries in ξ.
///   `view_blend = ViewBlend::kNearest` selects the nearest view's table alone (for comparison;
///   bench/light_sampler_bench.cpp measures both).
/// - Uniform component: each cell's probability is (1 − ε) · L_cell / Σ L + ε / R² with
///   ε = `uniform_fraction` (default 0.1). Because the grid is equal-area and the cells are
///   sampled uniformly inside, this is exactly the mixture of the tabulated distribution
///   (weight 1 − ε) with uniform hemisphere sampling (weight ε), folded into each table (and so
///   into their blend): the pdf is ≥ ε / (2π) everywhere on the hemisphere (the estimator's
///   weight value / pdf is at most 2π · value / ε), and one inverse CDF samples the mixture. A
///   tile whose values are all zero (or not finite) gets the uniform distribution.
/// - Sampling: ξ1 picks a row by the inverse of the (blended) marginal row CDF, ξ2 a column by
///   the inverse of that row's (blended) conditional CDF; the remainder of each ξ inside its CDF
///   step places the point continuously inside the cell, so ξ → ωi is continuous along ξ2 and,
///   within a row, along ξ1 (only row changes break it). pdf = blended cell probability /
///   (2π / R²). sample() reports the pdf that pdf() computes for the returned direction, so the
///   two agree exactly even for a point on a cell boundary.
/// - Caching: tables are built on first use per (tile, view) and published in a flat array of
///   atomic pointers (tiles × views entries, 8 bytes each): a lookup is one acquire load, a miss
///   builds the table and publishes it by compare-exchange (two threads that miss together both
///   build it; one keeps its copy). Tables are deterministic, so results do not depend on which
///   thread built a table or on the thread count.
///
/// Costs (R = 32, k = 4): a table holds (R + 1)² floats = 4.3 KiB; a 256² material sampled at
/// 81 views has 16 × 16 tiles × 81 views = 20 736 tables, 86 MiB when all are built. Building a
/// table evaluates R² · k² = 16 384 values in one eval_batch() whose consecutive queries share
/// their directions (a factorized material reuses the angular part over the 16 points). A
/// sample costs an AngularInterpolator lookup for the view weights, two binary searches over
/// 33 blended CDF entries, the square→hemisphere map and back, and one eval() for the value.
/// bench/light_sampler_bench.cpp measures all of it.
///
/// Albedo: a(x, ωo) = (1/π) Σ_cells value(x, ωi_cell, ωo) · 2π / Ra² with ωi_cell the centre
/// direction of each cell of an Ra × Ra equal-area grid (Ra = 32 by default): the midpoint rule
/// on the equal-area grid, evaluated at the query's uv and ωo exactly (no tile, no view blend).
/// For a Lambertian surface it gives exactly ρ · (1 + 2/Ra²), 0.2 % high at Ra = 32 (cos θ =
/// 1 − r² on the concentric disk is quadratic across each cell; the test checks it). A call
/// costs Ra² evaluations (about 0.3 ms on an fmf material at Ra = 32).

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "btf/core/angular_interpolator.h"
#include "btf/core/material.h"

namespace btf {

/// Which views' tables serve a view direction ωo (see above).
enum class ViewBlend {
    kBarycentric,  ///< the ≤ 3 views around ωo, blended with the interpolator's weights
    kNearest,      ///< the nearest sampled view alone
};

struct LightSamplerOptions {
    int tile_size = 16;       ///< texels per tile side (doubled until the tables fit the budget)
    int resolution = 32;      ///< R: the grid has R × R equal-area cells
    int points_per_side = 4;  ///< k: the table of a tile averages k × k points of it
    double uniform_fraction = 0.1;               ///< ε, in (0, 1]
    int64_t memory_budget = int64_t(256) << 20;  ///< bytes for all tables of the material
    ViewBlend view_blend = ViewBlend::kBarycentric;
};

class LightSampler {
  public:
    /// A sampler for `material`, which must outlive it. Throws btf::Error for options out of
    /// range or a material without views or texels.
    explicit LightSampler(const Material& material, const LightSamplerOptions& options = {});
    ~LightSampler();
    LightSampler(const LightSampler&) = delete;
    LightSampler& operator=(const LightSampler&) = delete;

    /// Draws a light direction (see Material::sample()). Thread-safe.
    LightSample sample(const Uv& uv, const Vec3& wo, double xi1, double xi2) const;
    /// The density of sample() at `wi` (see Material::pdf()). Thread-safe.
    double pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const;
    /// A direction drawn from the table of texel (x, y)'s tile and sampled view `view` alone (no
    /// blend over views: the stochastic filter's selected view), and its pdf; value and weight
    /// are left zero for the caller. Throws btf::Error for a texel or view outside the material.
    LightSample sample_view(int x, int y, int view, double xi1, double xi2) const;
    /// The density sample_view() draws `wi` with.
    double pdf_view(int x, int y, int view, const Vec3& wi) const;

    /// Tile side in texels, after fitting the memory budget.
    int tile_size() const { return m_tile; }
    int tiles_x() const { return m_tiles_x; }
    int tiles_y() const { return m_tiles_y; }
    const LightSamplerOptions& options() const { return m_options; }
    /// Bytes of one table.
    int64_t table_bytes() const;
    /// Tables built so far (a table two threads built at once counts once).
    int64_t tables_built() const { return m_built.load(std::memory_order_relaxed); }

  private:
    struct Blend;
    Blend blend(const Uv& uv, const Vec3& wo) const;
    Blend one_view(int x, int y, int view) const;
    LightSample draw(const Blend& b, double xi1, double xi2) const;
    const float* table(int tile, int view) const;
    const float* build(int tile, int view) const;
    double blend_pdf(const Blend& b, const Vec3& wi) const;

    const Material& m_material;
    LightSamplerOptions m_options;
    int m_tile = 16, m_tiles_x = 1, m_tiles_y = 1, m_views = 1;
    std::unique_ptr<std::atomic<const float*>[]> m_tables;  // tiles × views, row-major by tile
    std::vector<Vec3> m_centres;  // the cells' centre directions, row-major
    std::unique_ptr<AngularInterpolator> m_views_interpolator;  // for ViewBlend::kBarycentric
    mutable std::atomic<int64_t> m_built{0};
};

/// Directional albedo by the midpoint rule on a `resolution`² equal-area grid of light
/// directions (see above), evaluated with one eval_batch() of resolution² queries. Throws
/// btf::Error for a resolution outside [1, 1024].
Rgb quadrature_albedo(const Material& material, const Uv& uv, const Vec3& wo, int resolution = 32);

}  // namespace btf
