// SPDX-License-Identifier: MIT
#include "btf/core/angular_interpolator.h"

#include <libqhull_r/libqhull_r.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <numeric>
#include <string>

#include "btf/core/hemisphere.h"
#include "btf/util/clones.h"
#include "btf/util/error.h"

namespace btf {

namespace {

// Directions closer than this (radians, ≈ chord length) are duplicates.
constexpr double kDuplicateTolerance = 1e-6;
// Directions this far below the horizon (in z) are rounding noise and clamped onto it.
constexpr double kHorizonTolerance = 1e-7;
// A query lies in a triangle when its smallest gnomonic coordinate is ≥ −kInside × their sum.
constexpr double kInside = 1e-10;
// The grid build uses a more generous test: extra candidates cost little, missing ones a lot.
constexpr double kInsideBuild = 1e-7;
constexpr int kAuxRingSize = 8;
const double kSin45 = std::sqrt(0.5);

// x² + y² + z², for prepare() and weights4() alike (see octahedral_square()).
template <typename V>
inline V squared_length(V x, V y, V z) {
    return x * x + y * y + z * z;
}

std::string describe(const DirectionSet& set) {
    return fmt::format("direction set '{}'", set.name().empty() ? "(unnamed)" : set.name());
}

struct HullFacet {
    std::array<int, 3> vertex;
    Vec3 normal;  // outward
};

// A Qhull run's state and message stream, released however the run ends.
class QhullRun {
  public:
    explicit QhullRun(const std::string& what) : m_qh(std::make_unique<qhT>()) {
        m_messages = open_memstream(&m_text, &m_text_size);
        if (!m_messages) fail("{}: cannot open a memory stream for Qhull's messages", what);
        qh_zero(m_qh.get(), m_messages);
    }
    ~QhullRun() {
        qh_freeqhull(m_qh.get(), !qh_ALL);
        int curlong = 0, totlong = 0;
        qh_memfreeshort(m_qh.get(), &curlong, &totlong);
        std::fclose(m_messages);
        std::free(m_text);
    }
    QhullRun(const QhullRun&) = delete;
    QhullRun& operator=(const QhullRun&) = delete;

    qhT* qh() { return m_qh.get(); }
    FILE* messages() { return m_messages; }
    /// The first line Qhull wrote (its error message).
    std::string first_message() {
        std::fflush(m_messages);
        std::string text(m_text ? m_text : "", m_text_size);
        return text.substr(0, text.find('\n'));
    }

  private:
    std::unique_ptr<qhT> m_qh;
    FILE* m_messages = nullptr;
    char* m_text = nullptr;
    size_t m_text_size = 0;
};

// Convex hull of `points` by Qhull; option "Qt" triangulates non-simplicial facets (cocircular
// points of a ring). Qhull's messages go to a memory stream: the library never prints.
std::vector<HullFacet> convex_hull(const std::vector<Vec3>& points, const std::string& what) {
    std::vector<coordT> coords;
    coords.reserve(points.size() * 3);
    for (const Vec3& p : points) coords.insert(coords.end(), {p.x, p.y, p.z});

    QhullRun run(what);
    qhT* qh = run.qh();
    char options[] = "qhull Qt";
    const int exitcode = qh_new_qhull(qh, 3, static_cast<int>(points.size()), coords.data(), False,
                                      options, nullptr, run.messages());
    if (exitcode != 0)
        fail("{}: Qhull cannot triangulate the directions (exit code {}): {}", what, exitcode,
             run.first_message());
    std::vector<HullFacet> facets;
    facetT* facet;
    vertexT *vertex, **vertexp;
    FORALLfacets {
        if (facet->visible) continue;
        HullFacet f{};
        int k = 0;
        FOREACHvertex_(facet->vertices) {
            if (k < 3) f.vertex[k] = qh_pointid(qh, vertex->point);
            ++k;
        }
        check(k == 3, "{}: Qhull returned a facet with {} vertices despite option 'Qt'", what, k);
        f.normal = {facet->normal[0], facet->normal[1], facet->normal[2]};
        facets.push_back(f);
    }
    return facets;
}

// atan on [−1, 1] by the polynomial of Abramowitz & Stegun 4.4.49 (|error| ≤ 1e-5 rad). The
// query's grid cell needs to be right only to a fraction of a cell: every cell's candidates
// also cover its eight neighbours.
inline double approximate_atan(double t) {
    const double t2 = t * t;
    return t *
           (0.9998660 + t2 * (-0.3302995 + t2 * (0.1801410 + t2 * (-0.0851330 + t2 * 0.0208351))));
}

Vec3 slerp(const Vec3& a, const Vec3& b, double angle, double s) {
    const double sa = std::sin(angle);
    if (sa < 1e-12) return normalize(a * (1 - s) + b * s);
    return a * (std::sin((1 - s) * angle) / sa) + b * (std::sin(s * angle) / sa);
}

}  // namespace

AngularInterpolator::AngularInterpolator(const DirectionSet& set, int grid_resolution)
    : m_set(set), m_resolution(grid_resolution) {
    const std::string what = describe(set);
    check(grid_resolution >= 1 && grid_resolution <= 1024,
          "{}: grid resolution {} is outside [1, 1024]", what, grid_resolution);
    check(!set.empty(), "{} is empty", what);
    const int n = set.size();
    m_vertices.reserve(n + 1 + kAuxRingSize);
    for (int i = 0; i < n; ++i) {
        const Vec3& v = set.vector(i);
        check(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z),
              "{}: direction {} is not finite", what, i);
        check(v.z >= -kHorizonTolerance,
              "{}: direction {} (theta {:.3f} deg, phi {:.3f} deg) is below the horizon", what, i,
              set[i].theta_deg(), set[i].phi_deg());
        m_vertices.push_back(normalize({v.x, v.y, std::max(v.z, 0.0)}));
    }

    // Duplicates: sweep over the directions sorted by x; only pairs within the tolerance in x
    // can coincide.
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return m_vertices[a].x < m_vertices[b].x; });
    for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j) {
            const Vec3& a = m_vertices[order[i]];
            const Vec3& b = m_vertices[order[j]];
            if (b.x - a.x > kDuplicateTolerance) break;
            if (length(a - b) <= kDuplicateTolerance) {
                const int lo = std::min(order[i], order[j]), hi = std::max(order[i], order[j]);
                fail("{}: directions {} and {} coincide (theta {:.3f} deg, phi {:.3f} deg)", what,
                     lo, hi, set[lo].theta_deg(), set[lo].phi_deg());
            }
        }

    triangulate();
    build_lookup();
}

void AngularInterpolator::triangulate() {
    const std::string what = describe(m_set);
    const int n = m_set.size();

    // A set that lies entirely on the horizon would leave the zenith outside every triangle's
    // cone: lift it (and later every query) to θ = 45°, keeping the azimuths.
    m_lifted = std::all_of(m_vertices.begin(), m_vertices.end(),
                           [](const Vec3& v) { return v.z <= 1e-9; });
    if (m_lifted)
        for (Vec3& v : m_vertices) v = {v.x * kSin45, v.y * kSin45, kSin45};

    // The pole alone closes the hull around the centre when the directions' azimuths surround
    // the zenith (every gap < 180°); otherwise a ring below the horizon is needed as well.
    std::vector<double> azimuths;
    double max_z = 0;
    for (const Vec3& v : m_vertices) {
        max_z = std::max(max_z, v.z);
        if (std::hypot(v.x, v.y) > 1e-9) azimuths.push_back(std::atan2(v.y, v.x));
    }
    std::sort(azimuths.begin(), azimuths.end());
    double max_gap = 2 * kPi;
    if (!azimuths.empty()) {
        max_gap = azimuths.front() + 2 * kPi - azimuths.back();
        for (size_t i = 1; i < azimuths.size(); ++i)
            max_gap = std::max(max_gap, azimuths[i] - azimuths[i - 1]);
    }
    const bool surrounded = max_gap < kPi - 1e-9;

    m_vertices.push_back({0, 0, -1});
    if (!surrounded) {
        // Depression δ of the ring: with the highest direction at θ0, the ring's 8 points and
        // that direction together leave no half-space through the centre empty as long as
        // tan δ < cos(π/8) · cot θ0; half of that keeps a margin.
        const double theta0 = std::acos(std::clamp(max_z, 0.0, 1.0));
        const double delta =
            std::min(std::atan(0.5 * std::cos(kPi / kAuxRingSize) / std::tan(theta0)), radians(45));
        for (int k = 0; k < kAuxRingSize; ++k) {
            const double phi = (k + 0.5) * 2 * kPi / kAuxRingSize;
            m_vertices.push_back({std::cos(phi) * std::cos(delta), std::sin(phi) * std::cos(delta),
                                  -std::sin(delta)});
        }
    }

    const std::vector<HullFacet> facets = convex_hull(m_vertices, what);
    std::vector<char> used(m_vertices.size(), 0);
    double total_area = 0;
    m_triangles.clear();
    for (const HullFacet& f : facets) {
        std::array<int, 3> v = f.vertex;
        Vec3 a = m_vertices[v[0]], b = m_vertices[v[1]], c = m_vertices[v[2]];
        Vec3 normal = cross(b - a, c - a);
        const double twice_area = length(normal);
        if (twice_area < 1e-14) continue;  // a zero-area sliver from triangulating a polygon
        if (dot(normal, f.normal) < 0) {
            std::swap(v[1], v[2]);
            std::swap(b, c);
            normal = -normal;
        }
        // For a triangle oriented outward, det(a, b, c) / (2 area) is the distance of its plane
        // from the centre: it must be positive for the triangle's cone to be a proper one.
        const double det = triple(a, b, c);
        check(det / twice_area > 1e-9,
              "{}: triangle of directions {}, {}, {} passes through the centre of the sphere", what,
              v[0], v[1], v[2]);
        total_area += spherical_triangle_area(a, b, c);
        for (int k : v) used[k] = 1;

        // Real vertices first (stable), then the inverse of the matrix [v0 v1 v2] by rows.
        std::stable_partition(v.begin(), v.end(), [n](int k) { return k < n; });
        Triangle t{};
        t.vertex = v;
        t.real = static_cast<int>(std::count_if(v.begin(), v.end(), [n](int k) { return k < n; }));
        for (int k = 0; k < 3; ++k) {
            t.real_mask[k] = v[k] < n ? 1.0 : 0.0;
            t.out_index[k] = v[k] < n ? v[k] : v[0];
        }
        const Vec3& p0 = m_vertices[v[0]];
        const Vec3& p1 = m_vertices[v[1]];
        const Vec3& p2 = m_vertices[v[2]];
        const double d = triple(p0, p1, p2);
        const Vec3 rows[3] = {cross(p1, p2) / d, cross(p2, p0) / d, cross(p0, p1) / d};
        for (int r = 0; r < 3; ++r) {
            t.inverse[3 * r + 0] = rows[r].x;
            t.inverse[3 * r + 1] = rows[r].y;
            t.inverse[3 * r + 2] = rows[r].z;
        }
        m_triangles.push_back(t);
    }
    check(std::abs(total_area - 4 * kPi) < 1e-6,
          "{}: the triangulation covers {:.9f} sr instead of the whole sphere", what, total_area);
    for (int i = 0; i < n; ++i)
        check(used[i], "{}: direction {} is too close to its neighbours to be triangulated", what,
              i);
}

inline Vec3 AngularInterpolator::prepare(const Vec3& direction) const {
    double x = direction.x, y = direction.y;
    double z = direction.z > 0 ? direction.z : 0.0;  // clamps to the horizon; NaN z → 0
    const double len2 = squared_length(x, y, z);
    if (!m_lifted && len2 >= 1e-200 && len2 <= 1e200) return {x, y, z};  // the usual case
    // Scaling by the largest component keeps tiny and huge vectors representable.
    const double m = std::max({std::abs(x), std::abs(y), z});
    if (!(m > 0) || !std::isfinite(m)) return m_lifted ? Vec3{kSin45, 0, kSin45} : Vec3{1, 0, 0};
    x /= m, y /= m, z /= m;  // (1 / m could overflow for subnormal m)
    if (m_lifted) {
        const double r = std::sqrt(x * x + y * y);
        if (!(r > 0)) return {kSin45, 0, kSin45};
        return {x / r * kSin45, y / r * kSin45, kSin45};
    }
    return {x, y, z};
}

namespace {

// The map that weights() grids: the upper half of the octahedral map, turned by 45° so that it
// fills the unit square. A vector (x, y, z) with z ≥ 0, not zero, goes to
//     q = (x, y) / (|x| + |y| + z),   (u, v) = ((q_x + q_y + 1) / 2, (q_x − q_y + 1) / 2):
// one division, no square root or arc tangent, and any length. The diamond |q_x| + |q_y| ≤ 1
// becomes the square; the zenith is its centre, the horizon its boundary.
//
// This arithmetic, the triangle test and the weights below are templates over V, a double or a
// vector of kWeightLanes doubles, so that weights() and weights4() run the same expressions
// (and GCC contracts them into the same fused multiply-adds): their results are equal bit for
// bit.
template <typename V>
inline V absolute(V x) {
    return x < 0 ? -x : x;
}
template <typename V>
inline void octahedral_square(V x, V y, V z, V& u, V& v) {
    const V s = 1 / (absolute(x) + absolute(y) + z);
    const V qx = x * s, qy = y * s;
    u = 0.5 * (qx + qy + 1);
    v = 0.5 * (qx - qy + 1);
}
inline SquarePoint octahedral_square(double x, double y, double z) {
    SquarePoint p;
    octahedral_square(x, y, z, p.u, p.v);
    return p;
}

// Its inverse: the unit vector of a point of [0,1]².
Vec3 octahedral_direction(double u, double v) {
    const double a = 2 * u - 1, b = 2 * v - 1;
    return normalize(Vec3{0.5 * (a + b), 0.5 * (a - b), 1 - std::max(std::abs(a), std::abs(b))});
}

// The unnormalized gnomonic coordinates l = M d of a prepared query in the triangle whose
// inverse matrix M is `m` (rows), and whether the query lies in the triangle.
template <typename V>
inline auto contains(const V* m, V x, V y, V z, V* l) {
    l[0] = m[0] * x + m[1] * y + m[2] * z;
    l[1] = m[3] * x + m[4] * y + m[5] * z;
    l[2] = m[6] * x + m[7] * y + m[8] * z;
    V smallest = l[0];
    smallest = l[1] < smallest ? l[1] : smallest;
    smallest = l[2] < smallest ? l[2] : smallest;
    return smallest >= -kInside * (l[0] + l[1] + l[2]);
}
inline bool contains(const double* m, const Vec3& d, double* l) {
    return contains(m, d.x, d.y, d.z, l);
}

// The weights of gnomonic coordinates l in a triangle whose vertices' real_mask is `real`:
// negative ones (a query on an edge, within kInside) and auxiliary vertices' dropped, the rest
// normalized. w[k] · inverse, with inverse = 1 / sum; sum ≤ 0 (or NaN) is the caller's case.
template <typename V>
inline void normalized_weights(const V* l, const V* real, V* w, V& sum, V& inverse) {
    // Branch-free: whether a query lands on the rim (2 weights) or not (3) is unpredictable.
#pragma GCC unroll 3
    for (int k = 0; k < 3; ++k) w[k] = (l[k] < 0 ? V{} : l[k]) * real[k];
    sum = w[0] + w[1] + w[2];
    inverse = 1 / sum;
}

typedef int64_t WeightLaneInts __attribute__((vector_size(32)));  // masks of WeightLanes

}  // namespace

inline AngularWeights AngularInterpolator::finish(const Triangle& t, const double* l) const {
    double w[3], sum, inverse;
    normalized_weights(l, t.real_mask.data(), w, sum, inverse);
    AngularWeights out;
    out.count = t.real;
    out.index = t.out_index;
    if (!(sum > 0)) {
        // Only reachable with weight on auxiliary vertices alone, which a query above the
        // horizon never has; give the triangle's first direction the full weight.
        out.weight = {1, 0, 0};
        return out;
    }
    out.weight = {static_cast<float>(w[0] * inverse), static_cast<float>(w[1] * inverse),
                  static_cast<float>(w[2] * inverse)};
    return out;
}

BTF_CLONES AngularWeights AngularInterpolator::weights(const Vec3& direction) const {
    const Vec3 d = prepare(direction);
    const SquarePoint p = octahedral_square(d.x, d.y, d.z);
    const int g = m_lookup.resolution;
    const int cell =
        std::min(static_cast<int>(p.v * g), g - 1) * g + std::min(static_cast<int>(p.u * g), g - 1);
    // The cell's two best-covering candidates, both tested: a query in a cell that an edge
    // crosses lies in either with odds a branch would mispredict. Only cells near a vertex need
    // a third, and those are few.
    const std::array<int32_t, 2> pair = m_lookup_pairs[cell];
    double a[3], b[3];
    const bool in_a = contains(m_triangles[pair[0]].inverse.data(), d, a);
    const bool in_b = contains(m_triangles[pair[1]].inverse.data(), d, b);
    if (in_a | in_b) {
        const double l[3] = {in_a ? a[0] : b[0], in_a ? a[1] : b[1], in_a ? a[2] : b[2]};
        return finish(m_triangles[in_a ? pair[0] : pair[1]], l);
    }
    const int32_t* end = m_lookup.triangles.data() + m_lookup.offsets[cell + 1];
    for (const int32_t* c = m_lookup.triangles.data() + m_lookup.offsets[cell] + 2; c < end; ++c)
        if (contains(m_triangles[*c].inverse.data(), d, a)) return finish(m_triangles[*c], a);
    m_fallbacks.value.fetch_add(1, std::memory_order_relaxed);
    return weights_brute_force(direction);
}

inline void AngularInterpolator::transpose_rows(const Triangle* const* t, WeightLanes* lanes) {
    typedef WeightLanes V;
    // Unrolled, so that the rows stay in registers rather than in an array in memory.
#pragma GCC unroll 3
    for (int block = 0; block < 3; ++block) {
        V r[4];
#pragma GCC unroll 4
        for (int j = 0; j < 4; ++j)
            std::memcpy(&r[j], reinterpret_cast<const std::byte*>(t[j]) + 32 * block, sizeof r[j]);
        const V t0 = __builtin_shufflevector(r[0], r[1], 0, 4, 2, 6);
        const V t1 = __builtin_shufflevector(r[0], r[1], 1, 5, 3, 7);
        const V t2 = __builtin_shufflevector(r[2], r[3], 0, 4, 2, 6);
        const V t3 = __builtin_shufflevector(r[2], r[3], 1, 5, 3, 7);
        lanes[4 * block + 0] = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
        lanes[4 * block + 1] = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
        lanes[4 * block + 2] = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
        lanes[4 * block + 3] = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
    }
}

// G groups of 4 lanes, group g looked up in interpolator *in[g]: each step done for every group
// before the next, so that the groups' chains of dependent steps (division, cell, candidate
// pair, rows, division) overlap.
template <int G>
void AngularInterpolator::weights_lanes(const AngularInterpolator* const* in,
                                        const Vec3* const* const* directions,
                                        AngularWeights* const* out) {
    typedef WeightLanes V;
    typedef WeightLaneInts I;
    static_assert(kWeightLanes == 4, "the transposes are 4 × 4");
    static_assert(offsetof(Triangle, real_mask) == 9 * sizeof(double));
    V x[G], y[G], z[G];
    I scalar[G], cell[G];
#pragma GCC unroll 2
    for (int g = 0; g < G; ++g) {
        const Vec3* const* d = directions[g];
        x[g] = V{d[0]->x, d[1]->x, d[2]->x, d[3]->x};
        y[g] = V{d[0]->y, d[1]->y, d[2]->y, d[3]->y};
        z[g] = V{d[0]->z, d[1]->z, d[2]->z, d[3]->z};
        z[g] = z[g] > 0 ? z[g] : V{};  // as prepare(): NaN z → 0
        const V len2 = squared_length(x[g], y[g], z[g]);
        // Lanes that prepare() would change, and lanes whose cell's two candidates both miss,
        // take weights() itself.
        scalar[g] = in[g]->m_lifted ? I{} - 1 : ~((len2 >= 1e-200) & (len2 <= 1e200));
        // Harmless stand-ins in those lanes.
        x[g] = scalar[g] ? V{} + 1 : x[g];
        y[g] = scalar[g] ? V{} : y[g];
        z[g] = scalar[g] ? V{} : z[g];
        V u, v;
        octahedral_square(x[g], y[g], z[g], u, v);
        const int res = in[g]->m_lookup.resolution;
        const I last = I{} + (res - 1);
        I row = __builtin_convertvector(v * double(res), I);
        I column = __builtin_convertvector(u * double(res), I);
        row = row < last ? row : last;
        column = column < last ? column : last;
        cell[g] = row * res + column;
    }
    const Triangle* ta[G][4];
    const Triangle* tb[G][4];
#pragma GCC unroll 2
    for (int g = 0; g < G; ++g)
#pragma GCC unroll 4
        for (int j = 0; j < 4; ++j) {
            const std::array<int32_t, 2> pair = in[g]->m_lookup_pairs[size_t(cell[g][j])];
            ta[g][j] = &in[g]->m_triangles[size_t(pair[0])];
            tb[g][j] = &in[g]->m_triangles[size_t(pair[1])];
        }
#pragma GCC unroll 2
    for (int g = 0; g < G; ++g) {
        // Each candidate's 12 doubles from inverse[0] (its matrix, then real_mask) in lanes:
        // three 4 × 4 transposes of rows loaded whole, instead of 48 loads into single lanes.
        V ma[12], mb[12];
        transpose_rows(ta[g], ma);
        transpose_rows(tb[g], mb);
        V a[3], b[3];
        const I in_a = contains(ma, x[g], y[g], z[g], a);
        const I in_b = contains(mb, x[g], y[g], z[g], b);
        scalar[g] |= ~(in_a | in_b);
        V l[3], real[3];
#pragma GCC unroll 4
        for (int k = 0; k < 3; ++k) {
            l[k] = in_a ? a[k] : b[k];
            real[k] = in_a ? ma[9 + k] : mb[9 + k];
        }
        V w[3], sum, inverse;
        normalized_weights(l, real, w, sum, inverse);
        const I positive = sum > 0;
#pragma GCC unroll 4
        for (int k = 0; k < 3; ++k) w[k] *= inverse;
#pragma GCC unroll 4
        for (int j = 0; j < 4; ++j) {
            AngularWeights& o = out[g][j];
            if (scalar[g][j]) {
                o = in[g]->weights(*directions[g][j]);
                continue;
            }
            const Triangle& t = *(in_a[j] ? ta[g][j] : tb[g][j]);
            o.count = t.real;
            o.index = t.out_index;
            o.weight = positive[j] ? std::array<float, 3>{static_cast<float>(w[0][j]),
                                                          static_cast<float>(w[1][j]),
                                                          static_cast<float>(w[2][j])}
                                   : std::array<float, 3>{1, 0, 0};
        }
    }
}

BTF_CLONES void AngularInterpolator::weights4(const std::array<const Vec3*, 4>& directions,
                                              std::array<AngularWeights, 4>& out) const {
    const AngularInterpolator* in[1] = {this};
    const Vec3* const* d[1] = {directions.data()};
    AngularWeights* o[1] = {out.data()};
    weights_lanes<1>(in, d, o);
}

BTF_CLONES void AngularInterpolator::weights4(const AngularInterpolator& a,
                                              const std::array<const Vec3*, 4>& a_directions,
                                              std::array<AngularWeights, 4>& a_out,
                                              const AngularInterpolator& b,
                                              const std::array<const Vec3*, 4>& b_directions,
                                              std::array<AngularWeights, 4>& b_out) {
    const AngularInterpolator* in[2] = {&a, &b};
    const Vec3* const* d[2] = {a_directions.data(), b_directions.data()};
    AngularWeights* o[2] = {a_out.data(), b_out.data()};
    weights_lanes<2>(in, d, o);
}

AngularWeights AngularInterpolator::weights_brute_force(const Vec3& direction) const {
    const Vec3 d = prepare(direction);
    const Triangle* best = nullptr;
    double best_score = -std::numeric_limits<double>::infinity();
    double best_l[3] = {0, 0, 0};
    for (const Triangle& t : m_triangles) {
        if (t.real == 0) continue;
        const double* m = t.inverse.data();
        const double l[3] = {m[0] * d.x + m[1] * d.y + m[2] * d.z,
                             m[3] * d.x + m[4] * d.y + m[5] * d.z,
                             m[6] * d.x + m[7] * d.y + m[8] * d.z};
        const double sum = l[0] + l[1] + l[2];
        if (!(sum > 0)) continue;  // the opposite cone
        const double score = std::min({l[0], l[1], l[2]}) / sum;
        if (score > best_score) {
            best_score = score, best = &t;
            std::copy(l, l + 3, best_l);
        }
    }
    // The triangles tile the sphere, so some triangle with a real vertex contains d (prepare()
    // returns a finite, non-zero vector); the nearest direction is a last resort all the same.
    if (!best) {
        const int nearest = m_set.nearest(d);
        return {{nearest, nearest, nearest}, {1, 0, 0}, 1};
    }
    return finish(*best, best_l);
}

AngularInterpolator::CandidateGrid AngularInterpolator::build_grid(GridMap map, int r) const {
    const int cells = r * r;
    // Points of the hemisphere on the square and back. Points of the octahedral square are all
    // above the horizon; the square map's too.
    auto to_square = [map](const Vec3& d) {
        return map == GridMap::kSquare ? hemisphere_to_square(d)
                                       : octahedral_square(d.x, d.y, std::max(d.z, 0.0));
    };
    auto to_hemisphere = [map](double u, double v) {
        return map == GridMap::kSquare ? square_to_hemisphere({u, v}) : octahedral_direction(u, v);
    };
    // Boundary curves are sampled at this angular step. The area-preserving map stretches arcs
    // by less than 1 square unit per radian, the octahedral one by less than 1.15 (measured
    // over 2·10⁷ random directions and tangents), so consecutive samples are less than a
    // quarter cell apart, and the one-cell dilation below covers everything between.
    const double step = (map == GridMap::kSquare ? 0.25 : 0.2) / r;
    const int horizon_samples = static_cast<int>(std::ceil(2 * kPi / step));

    auto cell_of = [&](const Vec3& d) {
        const SquarePoint p = to_square(d);
        return std::array<int, 2>{std::clamp(static_cast<int>(p.u * r), 0, r - 1),
                                  std::clamp(static_cast<int>(p.v * r), 0, r - 1)};
    };
    auto inside = [](const Triangle& t, const Vec3& d, double tolerance) {
        const double* m = t.inverse.data();
        const double l0 = m[0] * d.x + m[1] * d.y + m[2] * d.z;
        const double l1 = m[3] * d.x + m[4] * d.y + m[5] * d.z;
        const double l2 = m[6] * d.x + m[7] * d.y + m[8] * d.z;
        const double sum = l0 + l1 + l2;
        return sum > 0 && std::min({l0, l1, l2}) >= -tolerance * sum;
    };

    // Sample points of each cell: its four corners and its centre.
    std::vector<Vec3> corners((r + 1) * (r + 1));
    for (int j = 0; j <= r; ++j)
        for (int i = 0; i <= r; ++i)
            corners[j * (r + 1) + i] =
                to_hemisphere(static_cast<double>(i) / r, static_cast<double>(j) / r);
    std::vector<Vec3> centres(cells);
    for (int j = 0; j < r; ++j)
        for (int i = 0; i < r; ++i)
            centres[j * r + i] = to_hemisphere((i + 0.5) / r, (j + 0.5) / r);

    std::vector<std::vector<int32_t>> lists(cells);
    std::vector<char> marked(cells, 0);
    std::vector<int> touched;
    for (int ti = 0; ti < num_triangles(); ++ti) {
        const Triangle& t = m_triangles[ti];
        if (t.real == 0) continue;  // entirely below the horizon: no query can land there
        touched.clear();
        auto mark = [&](const Vec3& d) {
            const auto [i, j] = cell_of(d);
            if (!marked[j * r + i]) marked[j * r + i] = 1, touched.push_back(j * r + i);
        };
        // The part of the triangle's cone above the horizon is bounded by its edges (above the
        // horizon) and, for triangles reaching below, by an arc of the horizon itself.
        bool reaches_horizon = false;
        for (int e = 0; e < 3; ++e) {
            const Vec3& a = m_vertices[t.vertex[e]];
            const Vec3& b = m_vertices[t.vertex[(e + 1) % 3]];
            reaches_horizon |= a.z <= 1e-9;
            const double angle = std::acos(std::clamp(dot(a, b), -1.0, 1.0));
            const int n = std::max(1, static_cast<int>(std::ceil(angle / step)));
            for (int k = 0; k <= n; ++k) {
                const Vec3 p = slerp(a, b, angle, static_cast<double>(k) / n);
                if (p.z >= 0) mark(p);
            }
        }
        if (reaches_horizon)
            for (int k = 0; k < horizon_samples; ++k) {
                const double phi = 2 * kPi * k / horizon_samples;
                const Vec3 h{std::cos(phi), std::sin(phi), 0};
                if (inside(t, h, kInsideBuild)) mark(h);
            }
        if (touched.empty()) continue;
        // The region is enclosed by its boundary, hence by the boundary cells' bounding box:
        // cells there that hold a sample point inside the triangle overlap it as well.
        int i0 = r, i1 = -1, j0 = r, j1 = -1;
        for (int c : touched) {
            i0 = std::min(i0, c % r), i1 = std::max(i1, c % r);
            j0 = std::min(j0, c / r), j1 = std::max(j1, c / r);
        }
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i) {
                const int c = j * r + i;
                if (marked[c]) continue;
                const Vec3* samples[5] = {
                    &centres[c], &corners[j * (r + 1) + i], &corners[j * (r + 1) + i + 1],
                    &corners[(j + 1) * (r + 1) + i], &corners[(j + 1) * (r + 1) + i + 1]};
                for (const Vec3* s : samples)
                    if (inside(t, *s, kInsideBuild)) {
                        marked[c] = 1, touched.push_back(c);
                        break;
                    }
            }
        for (int c : touched) {
            lists[c].push_back(ti);
            marked[c] = 0;
        }
    }

    // One-cell dilation, then order each cell's candidates by how much of the cell they cover
    // (counted on a 4×4 set of sample points) so that a query usually succeeds at the first.
    constexpr int kSub = 4;
    CandidateGrid grid;
    grid.resolution = r;
    grid.offsets.assign(cells + 1, 0);
    std::vector<int32_t> merged;
    std::vector<std::pair<int, int32_t>> ranked;
    std::array<Vec3, kSub * kSub> sub;
    for (int j = 0; j < r; ++j)
        for (int i = 0; i < r; ++i) {
            merged.clear();
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int ii = i + di, jj = j + dj;
                    if (ii < 0 || jj < 0 || ii >= r || jj >= r) continue;
                    const auto& l = lists[jj * r + ii];
                    merged.insert(merged.end(), l.begin(), l.end());
                }
            std::sort(merged.begin(), merged.end());
            merged.erase(std::unique(merged.begin(), merged.end()), merged.end());
            ranked.clear();
            if (merged.size() > 1)
                for (int sj = 0; sj < kSub; ++sj)
                    for (int si = 0; si < kSub; ++si)
                        sub[sj * kSub + si] =
                            to_hemisphere((i + (si + 0.5) / kSub) / r, (j + (sj + 0.5) / kSub) / r);
            for (int32_t ti : merged) {
                int hits = 0;
                if (merged.size() > 1)
                    for (const Vec3& s : sub) hits += inside(m_triangles[ti], s, kInside);
                ranked.emplace_back(-hits, ti);
            }
            std::sort(ranked.begin(), ranked.end());
            for (const auto& [hits, ti] : ranked) grid.triangles.push_back(ti);
            grid.offsets[j * r + i + 1] = static_cast<int32_t>(grid.triangles.size());
            check(!ranked.empty(), "{}: grid cell ({}, {}) has no candidate triangles",
                  describe(m_set), i, j);
        }
    return grid;
}

void AngularInterpolator::build_lookup() {
    // About 40 cells per triangle: edges then cross a sixth of the cells, and vertices (where
    // more than two candidates are needed) a few percent.
    const int r = std::clamp(static_cast<int>(std::ceil(6.5 * std::sqrt(num_triangles()))), 8, 512);
    m_lookup = build_grid(GridMap::kOctahedral, r);
    m_lookup_pairs.resize(size_t(r) * r);
    for (int c = 0; c < r * r; ++c) {
        const int32_t* list = m_lookup.triangles.data() + m_lookup.offsets[c];
        const int size = m_lookup.offsets[c + 1] - m_lookup.offsets[c];
        m_lookup_pairs[c] = {list[0], list[size > 1 ? 1 : 0]};
    }
}

AngularInterpolator::Tables AngularInterpolator::tables() const {
    Tables out;
    out.grid_resolution = m_resolution;
    out.num_directions = m_set.size();
    out.num_vertices = static_cast<int>(m_vertices.size());
    out.lifted_horizon = m_lifted;
    out.vertices.reserve(m_vertices.size() * 3);
    for (const Vec3& v : m_vertices)
        out.vertices.insert(out.vertices.end(), {static_cast<float>(v.x), static_cast<float>(v.y),
                                                 static_cast<float>(v.z)});
    out.triangles.reserve(m_triangles.size() * 3);
    out.inverse.reserve(m_triangles.size() * 9);
    for (const Triangle& t : m_triangles) {
        out.triangles.insert(out.triangles.end(), t.vertex.begin(), t.vertex.end());
        for (double m : t.inverse) out.inverse.push_back(static_cast<float>(m));
    }
    CandidateGrid grid = build_grid(GridMap::kSquare, m_resolution);
    out.cell_offsets = std::move(grid.offsets);
    out.cell_triangles = std::move(grid.triangles);
    return out;
}

}  // namespace btf
