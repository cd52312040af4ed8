// SPDX-License-Identifier: MIT
#pragma once
/// Barycentric interpolation over the directions of a DirectionSet: the one angular interpolator
/// that the evaluators, the renderer, the metrics and the WebGL viewer share.
///
/// Construction triangulates the set on the sphere (spherical Delaunay = convex hull of the unit
/// vectors, computed by Qhull with option "Qt" so that cocircular ring points give triangles) and
/// builds a lookup grid that finds the triangle of any query in O(1): a grid over the turned
/// octahedral map of the hemisphere (one division per query) whose cells keep the triangles
/// that overlap them, the two that cover most of the cell tested at once. A second grid, over
/// the area-preserving square map, goes to the viewer's shader with tables(). A query's weights
/// are the gnomonic (ray–plane) barycentric coordinates in its triangle (a, b, c):
///     w_a ∝ det(d, b, c),  w_b ∝ det(a, d, c),  w_c ∝ det(a, b, d),  normalized to sum 1,
/// which are exact at the vertices and continuous across shared edges.
///
/// The open rim. Auxiliary vertices below the horizon close the hull: always the south pole
/// (0, 0, −1), and for sets whose azimuths do not surround the zenith also a ring of 8 points a
/// little below the horizon. A query never gets weight on an auxiliary vertex: its weight is
/// dropped and the remaining weights renormalized. A query in a "rim" triangle (pole, a, b) below
/// the outermost ring therefore gets weights on a and b that depend on its azimuth only (it is
/// projected onto the rim edge along its meridian), continuous with the triangles above.
///
/// Queries need not be unit vectors; a query below the horizon is clamped to the horizon at its
/// azimuth; a query without any such direction (zero, straight down, not finite) is treated as +x
/// on the horizon.
///
/// Degenerate sets (see docs/interpolation.md):
/// - one direction: weight 1 on it everywhere;
/// - two directions, or directions whose azimuths leave a gap of 180° or more (a partial ring, a
///   meridian): the auxiliary ring closes the hull; in a triangle with a single real vertex
///   (away from the directions) that direction takes the full weight;
/// - all directions on one ring above the horizon: the ring polygon is split into a triangle fan
///   (Qhull's "Qt"), the rim is handled as above;
/// - all directions on the horizon: the set and every query are lifted to θ = 45° at their own
///   azimuth before the lookup, so the weights depend on the query's azimuth only (the zenith,
///   which has no azimuth, counts as φ = 0).
/// Empty sets, duplicate directions (closer than 1e-6 rad) and directions below the horizon are
/// rejected with btf::Error.
///
/// weights() is thread-safe, allocation-free and non-virtual.

#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

#include "btf/core/direction.h"
#include "btf/core/math.h"

namespace btf {

/// Up to three directions of a DirectionSet and their barycentric weights (≥ 0, sum 1).
struct AngularWeights {
    std::array<int, 3> index{};     ///< indices into the DirectionSet
    std::array<float, 3> weight{};  ///< barycentric weights; unused entries have weight 0
    int count = 0;                  ///< 1, 2 (on the rim) or 3
};

class AngularInterpolator {
  public:
    /// The triangulation and the lookup grid as plain arrays, so that a GPU shader can perform
    /// exactly the same lookup (docs/interpolation.md describes the algorithm step by step).
    struct Tables {
        /// R: the grid has R × R cells over the square [0,1]² of hemisphere_to_square(). A
        /// square point (u, v) lies in column min(⌊u·R⌋, R−1), row min(⌊v·R⌋, R−1); its cell
        /// index is row · R + column.
        int grid_resolution = 0;
        /// N: vertices [0, N) are the set's directions in set order; vertices [N, num_vertices)
        /// are auxiliary vertices below the horizon (the first of them is the south pole).
        int num_directions = 0;
        int num_vertices = 0;
        /// True when every direction lies on the horizon: `vertices` then holds the directions
        /// lifted to θ = 45°, and a query must be lifted the same way, (x, y, z) →
        /// (x̂·sin 45°, ŷ·sin 45°, cos 45°) with (x̂, ŷ) its normalized azimuth ((1, 0) if none).
        bool lifted_horizon = false;
        /// Unit vectors, 3 floats (x, y, z) per vertex.
        std::vector<float> vertices;
        /// 3 vertex indices per triangle. Real vertices come first; an index ≥ N marks an
        /// auxiliary vertex, whose weight is dropped (a rim triangle holds the pole index N).
        std::vector<int32_t> triangles;
        /// 9 floats per triangle: the rows of the inverse of the 3×3 matrix whose columns are the
        /// triangle's vertices (in `triangles` order). Row i · d is the unnormalized gnomonic
        /// weight of vertex i; d lies in the triangle when all three are ≥ 0.
        std::vector<float> inverse;
        /// R² + 1 offsets into cell_triangles: the candidates of cell k are
        /// cell_triangles[cell_offsets[k] .. cell_offsets[k + 1]).
        std::vector<int32_t> cell_offsets;
        /// Triangle indices; every triangle that overlaps a cell is among its candidates.
        std::vector<int32_t> cell_triangles;
    };

    /// Triangulates `set` (spherical Delaunay via Qhull) and builds the O(1) lookup grid of
    /// weights() (its resolution follows the number of triangles). `grid_resolution` (1 to 1024)
    /// is that of the exported tables' grid. Throws btf::Error for an empty set, duplicate
    /// directions, directions below the horizon or a bad resolution.
    explicit AngularInterpolator(const DirectionSet& set, int grid_resolution = 64);

    const DirectionSet& directions() const { return m_set; }

    /// Weights for any direction (need not be unit length). Directions below the outermost ring
    /// are projected onto the rim; directions below the horizon are clamped to it.
    AngularWeights weights(const Vec3& direction) const;
    AngularWeights weights(const Direction& d) const { return weights(d.vector()); }

    /// weights() of 4 directions at once, for batches: the lanes of vectors of doubles do the
    /// arithmetic of the four lookups together, and each result equals weights()'s bit for bit.
    void weights4(const std::array<const Vec3*, 4>& directions,
                  std::array<AngularWeights, 4>& out) const;
    /// a.weights4(a_directions, a_out) and b.weights4(b_directions, b_out) in one: the steps of
    /// both lookups interleaved, so that their chains of dependent steps overlap (a batch's view
    /// and light lookups).
    static void weights4(const AngularInterpolator& a,
                         const std::array<const Vec3*, 4>& a_directions,
                         std::array<AngularWeights, 4>& a_out, const AngularInterpolator& b,
                         const std::array<const Vec3*, 4>& b_directions,
                         std::array<AngularWeights, 4>& b_out);

    /// The same weights found by testing every triangle instead of the grid's candidates (slow;
    /// the reference for tests).
    AngularWeights weights_brute_force(const Vec3& direction) const;

    /// The exported tables' grid resolution (the constructor's argument).
    int grid_resolution() const { return m_resolution; }
    /// The resolution of weights()' own grid over the octahedral map.
    int lookup_resolution() const { return m_lookup.resolution; }
    /// Triangles of the closed triangulation, auxiliary-only ones included.
    int num_triangles() const { return static_cast<int>(m_triangles.size()); }
    /// Auxiliary vertices added below the horizon (1 = the pole only).
    int num_auxiliary_vertices() const {
        return static_cast<int>(m_vertices.size()) - m_set.size();
    }
    /// Vertex indices of triangle t (real vertices first; ≥ directions().size() = auxiliary).
    std::array<int, 3> triangle(int t) const { return m_triangles[t].vertex; }
    /// Vertex v as a unit vector (v < directions().size(): the direction, lifted to 45° when all
    /// directions lie on the horizon; otherwise an auxiliary vertex).
    const Vec3& vertex(int v) const { return m_vertices[v]; }

    /// The triangulation and a grid of grid_resolution² cells over hemisphere_to_square() as
    /// plain arrays for export (e.g. to a WebGL shader); the grid is built by each call.
    Tables tables() const;

    /// How many weights() queries found no containing candidate in their cell and fell back to
    /// the brute-force search (a numerical edge case; stays 0 in practice).
    int64_t fallback_count() const { return m_fallbacks.value.load(std::memory_order_relaxed); }

  private:
    struct Triangle {
        std::array<double, 9> inverse;    // rows of [v0 v1 v2]⁻¹
        std::array<double, 3> real_mask;  // 1 for real vertices, 0 for auxiliary ones
        std::array<int, 3> vertex;        // real vertices first
        std::array<int, 3> out_index;     // vertex, with auxiliary ones replaced by vertex[0]
        int real;                         // number of real vertices (1..3; 0 = auxiliary only)
    };
    // A copyable relaxed counter, so that the interpolator stays a value type.
    struct Counter {
        mutable std::atomic<int64_t> value{0};
        Counter() = default;
        Counter(const Counter& o) : value(o.value.load(std::memory_order_relaxed)) {}
        Counter& operator=(const Counter& o) {
            value.store(o.value.load(std::memory_order_relaxed), std::memory_order_relaxed);
            return *this;
        }
    };

    // A grid of candidate triangles over a map of the hemisphere onto [0,1]²: for each of its
    // resolution² cells, every triangle that overlaps the cell or a neighbour, the ones that
    // cover most of the cell first.
    struct CandidateGrid {
        int resolution = 0;
        std::vector<int32_t> offsets;    // resolution² + 1
        std::vector<int32_t> triangles;  // cell k: triangles[offsets[k] .. offsets[k + 1])
    };
    // kSquare: hemisphere_to_square(), the exported tables' map (the viewer's shader uses it).
    // kOctahedral: the turned octahedral map, one division per query, which weights() uses.
    enum class GridMap { kSquare, kOctahedral };

    // The lanes of weights4(): vectors of 4 doubles.
    static constexpr int kWeightLanes = 4;
    typedef double WeightLanes __attribute__((vector_size(8 * kWeightLanes)));
    template <int G>
    static void weights_lanes(const AngularInterpolator* const* interpolators,
                              const Vec3* const* const* directions, AngularWeights* const* out);
    // The first 12 doubles of 4 triangles (inverse, real_mask) as 12 vectors of their lanes.
    static void transpose_rows(const Triangle* const* t, WeightLanes* lanes);

    Vec3 prepare(const Vec3& direction) const;
    AngularWeights finish(const Triangle& t, const double* gnomonic) const;
    void triangulate();
    CandidateGrid build_grid(GridMap map, int resolution) const;
    void build_lookup();

    DirectionSet m_set;
    int m_resolution = 0;  // of the exported tables' grid
    bool m_lifted = false;
    std::vector<Vec3> m_vertices;  // directions (maybe lifted), then auxiliary vertices
    std::vector<Triangle> m_triangles;
    CandidateGrid m_lookup;                              // weights()' grid (octahedral)
    std::vector<std::array<int32_t, 2>> m_lookup_pairs;  // its cells' first two candidates
    Counter m_fallbacks;
};

}  // namespace btf
