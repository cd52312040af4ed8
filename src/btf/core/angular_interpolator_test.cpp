// SPDX-License-Identifier: MIT
#include "btf/core/angular_interpolator.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "btf/core/hemisphere.h"
#include "btf/util/error.h"

namespace btf {
namespace {

using ::testing::HasSubstr;

Vec3 random_sphere(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> uni(-1, 1);
    const double z = uni(rng), phi = kPi * uni(rng), s = std::sqrt(1 - z * z);
    return {s * std::cos(phi), s * std::sin(phi), z};
}

// A mix that stresses every region: the whole sphere (half of it below the horizon, which is
// clamped), the band below the outer rings, the horizon itself and the zenith area.
Vec3 random_query(std::mt19937_64& rng, int i) {
    std::uniform_real_distribution<double> uni(0, 1);
    const double phi = 2 * kPi * uni(rng);
    switch (i % 5) {
        case 0:
        case 1:
            return random_sphere(rng);
        case 2:
            return Direction{radians(70 + 20 * uni(rng)), phi}.vector();
        case 3:
            return Direction{kPi / 2, phi}.vector();
        default:
            return Direction{radians(20 * uni(rng)), phi}.vector() * (0.1 + 10 * uni(rng));
    }
}

// 200 directions spread over the hemisphere (at least 3° apart), a few of them on the horizon.
DirectionSet random_set(uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<Direction> dirs;
    std::vector<Vec3> vecs;
    while (dirs.size() < 200) {
        const bool horizon = dirs.size() < 6;
        const Direction d{horizon ? kPi / 2 : std::acos(uni(rng)), 2 * kPi * uni(rng)};
        const Vec3 v = d.vector();
        bool ok = true;
        for (const Vec3& w : vecs) ok &= dot(v, w) < std::cos(radians(3));
        if (!ok) continue;
        dirs.push_back(d);
        vecs.push_back(v);
    }
    return DirectionSet("random200", dirs);
}

DirectionSet ring(const std::string& name, double theta_deg, int count, double phi0_deg = 0,
                  double phi_step_deg = -1) {
    if (phi_step_deg < 0) phi_step_deg = 360.0 / count;
    std::vector<Direction> dirs;
    for (int i = 0; i < count; ++i)
        dirs.push_back(Direction::from_degrees(theta_deg, phi0_deg + i * phi_step_deg));
    return DirectionSet(name, dirs);
}

// Weights as a dense vector over the set's directions.
std::vector<double> dense(const AngularWeights& w, int n) {
    std::vector<double> out(n, 0.0);
    for (int i = 0; i < w.count; ++i) out.at(w.index[i]) += w.weight[i];
    return out;
}

double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
    double m = 0;
    for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
    return m;
}

void expect_valid(const AngularWeights& w, int n, const Vec3& query) {
    ASSERT_GE(w.count, 1) << query.x << " " << query.y << " " << query.z;
    ASSERT_LE(w.count, 3);
    double sum = 0;
    for (int i = 0; i < 3; ++i) {
        ASSERT_GE(w.index[i], 0);
        ASSERT_LT(w.index[i], n);
        ASSERT_GE(w.weight[i], 0.0f);
        if (i >= w.count) {
            ASSERT_EQ(w.weight[i], 0.0f);
        }
        sum += w.weight[i];
    }
    ASSERT_NEAR(sum, 1.0, 1e-6) << query.x << " " << query.y << " " << query.z;
}

// Independent reference: the weights from the exported tables, testing every triangle in
// float arithmetic, as a shader without the grid would.
std::vector<double> reference_weights(const AngularInterpolator::Tables& t, Vec3 q) {
    q.z = std::max(q.z, 0.0);
    if (t.lifted_horizon) {
        const double r = std::hypot(q.x, q.y);
        q = r > 0 ? Vec3{q.x / r * std::sqrt(0.5), q.y / r * std::sqrt(0.5), std::sqrt(0.5)}
                  : Vec3{std::sqrt(0.5), 0, std::sqrt(0.5)};
    }
    q = normalize(q);
    const int triangles = static_cast<int>(t.triangles.size() / 3);
    int best = -1;
    double best_score = -1e300;
    std::array<double, 3> best_l{};
    for (int k = 0; k < triangles; ++k) {
        std::array<double, 3> l{};
        for (int r = 0; r < 3; ++r)
            l[r] = t.inverse[9 * k + 3 * r] * q.x + t.inverse[9 * k + 3 * r + 1] * q.y +
                   t.inverse[9 * k + 3 * r + 2] * q.z;
        bool has_real = false;
        for (int r = 0; r < 3; ++r) has_real |= t.triangles[3 * k + r] < t.num_directions;
        const double sum = l[0] + l[1] + l[2];
        if (!has_real || sum <= 0) continue;
        const double score = std::min({l[0], l[1], l[2]}) / sum;
        if (score > best_score) best_score = score, best = k, best_l = l;
    }
    std::vector<double> out(t.num_directions, 0.0);
    double sum = 0;
    for (int r = 0; r < 3; ++r) {
        const int v = t.triangles[3 * best + r];
        if (v >= t.num_directions) continue;
        out[v] += std::max(best_l[r], 0.0);
        sum += std::max(best_l[r], 0.0);
    }
    for (double& w : out) w /= sum;
    return out;
}

// The documented shader algorithm, run on the exported tables in float arithmetic.
std::vector<double> shader_weights(const AngularInterpolator::Tables& t, const Vec3& query) {
    Vec3 q{query.x, query.y, std::max(query.z, 0.0)};
    const SquarePoint p = hemisphere_to_square(q);
    const int r = t.grid_resolution;
    const int cell = std::min(int(p.v * r), r - 1) * r + std::min(int(p.u * r), r - 1);
    q = normalize(q);
    for (int c = t.cell_offsets[cell]; c < t.cell_offsets[cell + 1]; ++c) {
        const int k = t.cell_triangles[c];
        float l[3];
        for (int row = 0; row < 3; ++row)
            l[row] = t.inverse[9 * k + 3 * row] * float(q.x) +
                     t.inverse[9 * k + 3 * row + 1] * float(q.y) +
                     t.inverse[9 * k + 3 * row + 2] * float(q.z);
        if (std::min({l[0], l[1], l[2]}) < -1e-6f * (l[0] + l[1] + l[2])) continue;
        std::vector<double> out(t.num_directions, 0.0);
        double sum = 0;
        for (int row = 0; row < 3; ++row)
            if (t.triangles[3 * k + row] < t.num_directions) {
                out[t.triangles[3 * k + row]] += std::max(l[row], 0.0f);
                sum += std::max(l[row], 0.0f);
            }
        for (double& w : out) w /= sum;
        return out;
    }
    ADD_FAILURE() << "no candidate triangle contains the query";
    return {};
}

class BuiltinAndRandomSets : public ::testing::TestWithParam<std::string> {
  protected:
    static DirectionSet make(const std::string& name) {
        if (name == "random200") return random_set(2024);
        return DirectionSet::named(name);
    }
};

TEST_P(BuiltinAndRandomSets, WeightOneAtEverySampleDirection) {
    const DirectionSet set = make(GetParam());
    const AngularInterpolator interp(set);
    for (int i = 0; i < set.size(); ++i) {
        for (const AngularWeights& w : {interp.weights(set.vector(i)), interp.weights(set[i]),
                                        interp.weights(set.vector(i) * 3.5)}) {
            const std::vector<double> d = dense(w, set.size());
            EXPECT_NEAR(d[i], 1.0, 1e-6) << "direction " << i;
        }
    }
    EXPECT_EQ(interp.fallback_count(), 0);
}

TEST_P(BuiltinAndRandomSets, PartitionOfUnityEverywhere) {
    const DirectionSet set = make(GetParam());
    const AngularInterpolator interp(set);
    std::mt19937_64 rng(1);
    for (int i = 0; i < 100000; ++i) {
        const Vec3 q = random_query(rng, i);
        ASSERT_NO_FATAL_FAILURE(expect_valid(interp.weights(q), set.size(), q));
    }
    EXPECT_EQ(interp.fallback_count(), 0);
}

TEST_P(BuiltinAndRandomSets, AgreesWithBruteForceSearch) {
    const DirectionSet set = make(GetParam());
    const AngularInterpolator interp(set);
    const AngularInterpolator::Tables tables = interp.tables();
    std::mt19937_64 rng(2);
    double worst_internal = 0, worst_reference = 0;
    for (int i = 0; i < 100000; ++i) {
        const Vec3 q = random_query(rng, i);
        const std::vector<double> w = dense(interp.weights(q), set.size());
        worst_internal = std::max(
            worst_internal, max_difference(w, dense(interp.weights_brute_force(q), set.size())));
        if (i % 10 == 0)  // the float reference tests every triangle: slower
            worst_reference =
                std::max(worst_reference, max_difference(w, reference_weights(tables, q)));
    }
    EXPECT_LT(worst_internal, 1e-6);
    EXPECT_LT(worst_reference, 1e-5);
    EXPECT_EQ(interp.fallback_count(), 0) << "queries that missed their grid cell's candidates";
}

// weights() grids the octahedral map, whose cells fold along the octants' boundaries (the planes
// x = 0 and y = 0, the square's diagonals) and end at the horizon (its border): queries on and
// next to those lines, at every height, against the brute-force search.
TEST_P(BuiltinAndRandomSets, LookupGridHoldsOnTheOctantBoundaries) {
    const DirectionSet set = make(GetParam());
    const AngularInterpolator interp(set);
    EXPECT_EQ(interp.lookup_resolution(),
              static_cast<int>(std::ceil(6.5 * std::sqrt(interp.num_triangles()))));
    double worst = 0;
    for (int k = 0; k < 4; ++k)
        for (const double offset : {0.0, 1e-12, -1e-12, 1e-7, -1e-7}) {
            const double phi = k * kPi / 2 + offset;
            for (int j = 0; j <= 2000; ++j) {
                const Vec3 q = Direction{kPi / 2 * j / 2000, phi}.vector();
                worst = std::max(worst,
                                 max_difference(dense(interp.weights(q), set.size()),
                                                dense(interp.weights_brute_force(q), set.size())));
            }
        }
    EXPECT_LT(worst, 1e-6);
    EXPECT_EQ(interp.fallback_count(), 0);
}

TEST_P(BuiltinAndRandomSets, ContinuousForNearbyDirections) {
    const DirectionSet set = make(GetParam());
    const AngularInterpolator interp(set);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> uni(0, 1);
    // A random value per direction; the interpolant's slope is bounded by the weights' slope
    // (≲ 100 per radian for these triangles), while a discontinuity would jump by O(0.1).
    std::vector<double> f(set.size());
    for (double& v : f) v = uni(rng);
    auto value = [&](const Vec3& q) {
        const AngularWeights w = interp.weights(q);
        double s = 0;
        for (int i = 0; i < w.count; ++i) s += w.weight[i] * f[w.index[i]];
        return s;
    };
    constexpr double kStep = 1e-5;
    double worst = 0;
    for (int i = 0; i < 100000; ++i) {
        const Vec3 a = random_query(rng, i);
        // Far below the horizon clamping follows the azimuth, which turns ever faster toward
        // straight down (where it is undefined): nearby pairs there are not nearby once clamped.
        if (a.z < -0.7) continue;
        const Vec3 axis = normalize(cross(a, random_sphere(rng)));
        const Vec3 b = a * std::cos(kStep) + cross(axis, a) * std::sin(kStep);
        worst = std::max(worst, std::abs(value(a) - value(b)));
    }
    EXPECT_LT(worst, 2e-3);

    // Across every edge: points on the edge, nudged 1e-8 rad to either side, must get the same
    // weights (the third weight vanishes on the edge in both triangles).
    double worst_edge = 0;
    for (int t = 0; t < interp.num_triangles(); ++t) {
        const auto v = interp.triangle(t);
        for (int e = 0; e < 3; ++e) {
            const Vec3 a = interp.vertex(v[e]), b = interp.vertex(v[(e + 1) % 3]);
            const Vec3 n = normalize(cross(a, b));
            for (int k = 1; k < 20; ++k) {
                const Vec3 p = normalize(a * (1 - k / 20.0) + b * (k / 20.0));
                if (p.z < 0) continue;
                const Vec3 p1 = p + n * 1e-8, p2 = p - n * 1e-8;
                worst_edge =
                    std::max(worst_edge, max_difference(dense(interp.weights(p1), set.size()),
                                                        dense(interp.weights(p2), set.size())));
            }
        }
    }
    EXPECT_LT(worst_edge, 1e-5);
    EXPECT_EQ(interp.fallback_count(), 0);
}

TEST_P(BuiltinAndRandomSets, ExportedTablesReproduceTheLookup) {
    const DirectionSet set = make(GetParam());
    const AngularInterpolator interp(set, 32);
    const AngularInterpolator::Tables t = interp.tables();
    const int r = t.grid_resolution;
    ASSERT_EQ(r, 32);
    ASSERT_EQ(t.num_directions, set.size());
    ASSERT_EQ(t.vertices.size(), 3u * t.num_vertices);
    ASSERT_EQ(t.triangles.size(), 3u * interp.num_triangles());
    ASSERT_EQ(t.inverse.size(), 9u * interp.num_triangles());
    ASSERT_EQ(t.cell_offsets.size(), size_t(r) * r + 1);
    EXPECT_EQ(t.cell_offsets.front(), 0);
    EXPECT_EQ(t.cell_offsets.back(), static_cast<int32_t>(t.cell_triangles.size()));
    for (int c = 0; c < r * r; ++c) {
        EXPECT_LT(t.cell_offsets[c], t.cell_offsets[c + 1]) << "cell " << c << " is empty";
    }
    for (int32_t k : t.cell_triangles) {
        ASSERT_GE(k, 0);
        ASSERT_LT(k, interp.num_triangles());
    }
    for (size_t k = 0; k < t.triangles.size(); k += 3) {
        for (int j = 0; j < 3; ++j) ASSERT_LT(t.triangles[k + j], t.num_vertices);
        // Real vertices first.
        if (t.triangles[k] >= t.num_directions) {
            EXPECT_GE(t.triangles[k + 1], t.num_directions);
        }
        if (t.triangles[k + 1] >= t.num_directions) {
            EXPECT_GE(t.triangles[k + 2], t.num_directions);
        }
    }
    for (int i = 0; i < t.num_vertices; ++i) {
        const Vec3 v{t.vertices[3 * i], t.vertices[3 * i + 1], t.vertices[3 * i + 2]};
        EXPECT_NEAR(length(v), 1, 1e-6);
        if (i < t.num_directions) {
            EXPECT_NEAR(length(v - set.vector(i)), 0, 1e-6);
        }
        if (i == t.num_directions) {
            EXPECT_EQ(v, (Vec3{0, 0, -1})) << "the pole comes first";
        }
        if (i >= t.num_directions) {
            EXPECT_LT(v.z, 0);
        }
    }
    std::mt19937_64 rng(4);
    double worst = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec3 q = random_query(rng, i);
        const std::vector<double> s = shader_weights(t, q);
        ASSERT_FALSE(s.empty());
        worst = std::max(worst, max_difference(s, dense(interp.weights(q), set.size())));
    }
    EXPECT_LT(worst, 1e-5);
}

INSTANTIATE_TEST_SUITE_P(Sets, BuiltinAndRandomSets,
                         ::testing::Values("ubo81", "dome151", "random200"));

TEST(AngularInterpolator, BuiltinTriangulations) {
    // UBO2003's rings are closed by the pole alone: 24 rim triangles below the 75° ring.
    for (const DirectionSet* set : {&DirectionSet::ubo81(), &DirectionSet::dome151()}) {
        const AngularInterpolator interp(*set);
        EXPECT_EQ(interp.num_auxiliary_vertices(), 1) << set->name();
        const AngularInterpolator::Tables t = interp.tables();
        int rim = 0;
        for (size_t k = 0; k < t.triangles.size(); k += 3) {
            const int v2 = t.triangles[k + 2];
            if (v2 >= t.num_directions) {
                ++rim;
                EXPECT_EQ(v2, t.num_directions) << "the pole";
                // Both real vertices lie on the outermost (75°) ring.
                EXPECT_NEAR((*set)[t.triangles[k]].theta_deg(), 75, 1e-9);
                EXPECT_NEAR((*set)[t.triangles[k + 1]].theta_deg(), 75, 1e-9);
            }
        }
        EXPECT_EQ(rim, 24) << set->name();
        // Euler: a closed triangulation of V vertices has 2V − 4 triangles.
        EXPECT_EQ(interp.num_triangles(), 2 * (set->size() + 1) - 4) << set->name();
    }
}

TEST(AngularInterpolator, RimProjection) {
    // UBO2003's outer ring: θ = 75°, 24 directions 15° apart, indices 57..80.
    const DirectionSet& set = DirectionSet::ubo81();
    const AngularInterpolator interp(set);
    const int a = 57, b = 58;
    ASSERT_NEAR(set[a].theta_deg(), 75, 1e-9);
    ASSERT_NEAR(set[a].phi_deg(), 0, 1e-9);
    ASSERT_NEAR(set[b].phi_deg(), 15, 1e-9);
    // Below the ring the weights depend on the azimuth only: (cos 5°, sin 5°) = λ·a + μ·b in
    // the plane gives λ ∝ sin 10°, μ ∝ sin 5°.
    const double wa = std::sin(radians(10)) / (std::sin(radians(10)) + std::sin(radians(5)));
    for (double theta : {78.0, 85.0, 89.9, 90.0, 120.0}) {
        const AngularWeights w = interp.weights(Direction::from_degrees(theta, 5));
        ASSERT_EQ(w.count, 2) << theta;
        const std::vector<double> d = dense(w, set.size());
        EXPECT_NEAR(d[a], wa, 1e-6) << theta;
        EXPECT_NEAR(d[b], 1 - wa, 1e-6) << theta;
    }
    // At a rim direction's own azimuth, below it, all weight goes to it.
    const std::vector<double> d = dense(interp.weights(Direction::from_degrees(88, 15)), 81);
    EXPECT_NEAR(d[b], 1, 1e-6);
    // Just above the great-circle edge between a and b, three directions share the weight.
    EXPECT_EQ(interp.weights(Direction::from_degrees(73, 7.5)).count, 3);
}

TEST(AngularInterpolator, QueriesWithoutDirection) {
    const AngularInterpolator interp(DirectionSet::ubo81());
    // Zero, straight down and NaN all count as +x on the horizon: the rim direction at φ = 0.
    for (const Vec3 q : {Vec3{0, 0, 0}, Vec3{0, 0, -2}, Vec3{NAN, 1, 1}, Vec3{1e-310, 0, 0}}) {
        const AngularWeights w = interp.weights(q);
        ASSERT_NO_FATAL_FAILURE(expect_valid(w, 81, q));
        EXPECT_NEAR(dense(w, 81)[57], 1, 1e-6);
    }
}

// weights4() is weights() four at a time, bit for bit: on every kind of set (the lifted horizon
// ring and a single direction included) and for every kind of query, the odd ones (zero, NaN,
// below the horizon, subnormal, huge), which take weights() itself, among ordinary ones in the
// other lanes.
TEST(AngularInterpolator, LanesEqualOneByOne) {
    const std::vector<DirectionSet> sets = {DirectionSet::ubo81(),
                                            DirectionSet::dome151(),
                                            random_set(2024),
                                            ring("horizon8", 90, 8),
                                            DirectionSet("one", {Direction::from_degrees(30, 40)}),
                                            ring("ring6", 40, 6)};
    const std::vector<Vec3> odd = {{0, 0, 0},
                                   {0, 0, -2},
                                   {NAN, 1, 1},
                                   {1, 1, NAN},
                                   {1e-310, 0, 0},
                                   {1e-150, 1e-150, 1e-150},
                                   {1e120, 3e120, 2e120},
                                   {INFINITY, 0, 1},
                                   {0, 0, 1},
                                   {1, 0, 0},
                                   {-0.0, -0.0, 1},
                                   {0.5, -0.5, 0}};
    for (const DirectionSet& set : sets) {
        const AngularInterpolator interp(set);
        std::mt19937_64 rng(9);
        std::vector<Vec3> queries;
        for (int i = 0; i < 40000; ++i) queries.push_back(random_query(rng, i));
        for (size_t i = 0; i < odd.size(); ++i) queries[i * 7 + 1] = odd[i];
        for (int i = 0; i < set.size(); ++i) queries.push_back(set.vector(i));
        while (queries.size() % 4 != 0) queries.push_back({0, 0, 1});
        int differences = 0;
        auto compare = [&](size_t i, const AngularWeights& lanes) {
            const AngularWeights one = interp.weights(queries[i]);
            const bool same =
                one.count == lanes.count && one.index == lanes.index &&
                std::memcmp(one.weight.data(), lanes.weight.data(), sizeof one.weight) == 0;
            if (!same && ++differences <= 3)
                ADD_FAILURE() << set.name() << ": query " << i << " (" << queries[i].x << ", "
                              << queries[i].y << ", " << queries[i].z << ")";
        };
        for (size_t i = 0; i < queries.size(); i += 4) {
            std::array<AngularWeights, 4> four;
            interp.weights4({&queries[i], &queries[i + 1], &queries[i + 2], &queries[i + 3]}, four);
            for (size_t j = 0; j < 4; ++j) compare(i + j, four[j]);
        }
        // Two lookups interleaved, here of the same interpolator (the batches pair a material's
        // views with its lights): each group as by itself.
        while (queries.size() % 8 != 0) queries.push_back({0, 0, 1});
        for (size_t i = 0; i < queries.size(); i += 8) {
            std::array<AngularWeights, 4> first, second;
            AngularInterpolator::weights4(
                interp, {&queries[i], &queries[i + 1], &queries[i + 2], &queries[i + 3]}, first,
                interp, {&queries[i + 4], &queries[i + 5], &queries[i + 6], &queries[i + 7]},
                second);
            for (size_t j = 0; j < 4; ++j) compare(i + j, first[j]), compare(i + 4 + j, second[j]);
        }
        EXPECT_EQ(differences, 0) << set.name();
    }
}

TEST(AngularInterpolator, CopiesBehaveAlike) {
    const AngularInterpolator a(DirectionSet::dome151());
    const AngularInterpolator b = a;
    std::mt19937_64 rng(5);
    for (int i = 0; i < 1000; ++i) {
        const Vec3 q = random_query(rng, i);
        EXPECT_EQ(dense(a.weights(q), 151), dense(b.weights(q), 151));
    }
    EXPECT_EQ(&b.directions(), &b.directions());
    EXPECT_TRUE(b.directions().same_directions(DirectionSet::dome151()));
}

// Degenerate sets: the common checks (exact at the samples, a partition of unity everywhere,
// agreement with brute force, no grid misses, continuity away from documented exceptions).
void check_degenerate(const DirectionSet& set, bool continuous = true) {
    const AngularInterpolator interp(set, 16);
    for (int i = 0; i < set.size(); ++i)
        EXPECT_NEAR(dense(interp.weights(set.vector(i)), set.size())[i], 1, 1e-6)
            << set.name() << " direction " << i;
    // Sets on the horizon get weights from the azimuth alone, undefined at the zenith.
    const bool lifted = interp.tables().lifted_horizon;
    std::mt19937_64 rng(6);
    double worst_brute = 0, worst_step = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec3 q = random_query(rng, i);
        const AngularWeights w = interp.weights(q);
        ASSERT_NO_FATAL_FAILURE(expect_valid(w, set.size(), q)) << set.name();
        const std::vector<double> d = dense(w, set.size());
        worst_brute = std::max(worst_brute,
                               max_difference(d, dense(interp.weights_brute_force(q), set.size())));
        const Vec3 q2 = normalize(q + random_sphere(rng) * 1e-6);
        if (q.z > 1e-3 && (!lifted || std::hypot(q.x, q.y) > 1e-2))
            worst_step =
                std::max(worst_step, max_difference(d, dense(interp.weights(q2), set.size())));
    }
    EXPECT_LT(worst_brute, 1e-6) << set.name();
    if (continuous) {
        EXPECT_LT(worst_step, 1e-3) << set.name();
    }
    EXPECT_EQ(interp.fallback_count(), 0) << set.name();
}

TEST(AngularInterpolator, SingleDirection) {
    for (const Direction d : {Direction::from_degrees(30, 40), Direction::from_degrees(0, 0),
                              Direction::from_degrees(90, 200)}) {
        const DirectionSet set("one", {d});
        check_degenerate(set);
        const AngularInterpolator interp(set);
        std::mt19937_64 rng(8);
        for (int i = 0; i < 1000; ++i) {
            const AngularWeights w = interp.weights(random_query(rng, i));
            EXPECT_EQ(w.count, 1);
            EXPECT_EQ(w.index[0], 0);
            EXPECT_EQ(w.weight[0], 1.0f);
        }
    }
}

TEST(AngularInterpolator, TwoDirections) {
    const DirectionSet set("two",
                           {Direction::from_degrees(30, 0), Direction::from_degrees(30, 90)});
    check_degenerate(set);
    const AngularInterpolator interp(set);
    EXPECT_EQ(interp.num_auxiliary_vertices(), 1 + 8) << "pole and ring";
    // Halfway along the great-circle arc, by symmetry, equal weights.
    const std::vector<double> mid =
        dense(interp.weights(set.vector(0) + set.vector(1)), set.size());
    EXPECT_NEAR(mid[0], 0.5, 1e-6);
    EXPECT_NEAR(mid[1], 0.5, 1e-6);
    // Far from both, opposite the first: all weight on the nearer direction of that sector.
    const std::vector<double> far = dense(interp.weights(Direction::from_degrees(60, 180)), 2);
    EXPECT_NEAR(far[0] + far[1], 1, 1e-6);
    // Two directions on opposite sides of the horizon circle work as well.
    check_degenerate(DirectionSet(
        "two-opposite", {Direction::from_degrees(90, 0), Direction::from_degrees(90, 180)}));
}

TEST(AngularInterpolator, OneRing) {
    // A full ring above the horizon: the pole closes it, the cap is a fan of triangles.
    const DirectionSet set = ring("ring45", 45, 6);
    check_degenerate(set);
    const AngularInterpolator interp(set);
    EXPECT_EQ(interp.num_auxiliary_vertices(), 1);
    const AngularWeights zenith = interp.weights(Vec3{0, 0, 1});
    EXPECT_EQ(zenith.count, 3);
    // Below the ring: rim projection between the two neighbours.
    const std::vector<double> rim = dense(interp.weights(Direction::from_degrees(80, 30)), 6);
    EXPECT_NEAR(rim[0], 0.5, 1e-6);
    EXPECT_NEAR(rim[1], 0.5, 1e-6);
}

TEST(AngularInterpolator, RingOnTheHorizon) {
    // Every direction on the horizon: the weights follow the query's azimuth alone (and jump
    // only at the zenith, which has none).
    const DirectionSet set = ring("horizon8", 90, 8);
    check_degenerate(set);
    const AngularInterpolator interp(set);
    EXPECT_TRUE(interp.tables().lifted_horizon);
    for (double theta : {10.0, 45.0, 80.0, 90.0, 135.0}) {
        const std::vector<double> w =
            dense(interp.weights(Direction::from_degrees(theta, 22.5)), 8);
        EXPECT_NEAR(w[0], 0.5, 1e-6) << theta;
        EXPECT_NEAR(w[1], 0.5, 1e-6) << theta;
        const std::vector<double> q =
            dense(interp.weights(Direction::from_degrees(theta, 45 + 15)), 8);
        EXPECT_NEAR(q[1] + q[2], 1, 1e-6) << theta;
        EXPECT_GT(q[1], q[2]) << theta;
    }
}

TEST(AngularInterpolator, PartialRingAndMeridian) {
    // Azimuths that leave a gap of 180° or more: an auxiliary ring below the horizon closes the
    // hull.
    const DirectionSet partial = ring("partial", 60, 3, 0, 30);
    check_degenerate(partial);
    EXPECT_EQ(AngularInterpolator(partial).num_auxiliary_vertices(), 9);
    // Directions on one meridian plane (coplanar with the pole).
    const DirectionSet meridian("meridian",
                                {Direction::from_degrees(0, 0), Direction::from_degrees(30, 0),
                                 Direction::from_degrees(60, 0), Direction::from_degrees(30, 180)});
    check_degenerate(meridian);
    // Between two of its directions, on the meridian: only those two.
    const AngularWeights w = AngularInterpolator(meridian).weights(Direction::from_degrees(45, 0));
    const std::vector<double> d = dense(w, 4);
    EXPECT_NEAR(d[1] + d[2], 1, 1e-6);
    EXPECT_GT(d[1], 0.1);
    EXPECT_GT(d[2], 0.1);
    // A quadrant of a random set.
    std::vector<Direction> quadrant;
    for (int i = 0; i < 5; ++i)
        for (int j = 0; j < 4; ++j)
            quadrant.push_back(Direction::from_degrees(10 + 15 * i, 10 + 20 * j + 3 * i));
    check_degenerate(DirectionSet("quadrant", quadrant));
}

TEST(AngularInterpolator, RejectsBadSets) {
    auto message = [](const DirectionSet& set, int resolution = 64) {
        try {
            AngularInterpolator interp(set, resolution);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_EQ(message(DirectionSet("none", {})), "direction set 'none' is empty");
    EXPECT_THAT(message(DirectionSet(
                    "dup", {Direction::from_degrees(30, 10), Direction::from_degrees(45, 10),
                            Direction::from_degrees(30, 10)})),
                HasSubstr("direction set 'dup': directions 0 and 2 coincide (theta 30.000 deg, "
                          "phi 10.000 deg)"));
    // The zenith has one direction, whatever its φ.
    EXPECT_THAT(message(DirectionSet(
                    "zenith", {Direction::from_degrees(0, 0), Direction::from_degrees(0, 90)})),
                HasSubstr("directions 0 and 1 coincide"));
    EXPECT_THAT(message(DirectionSet(
                    "low", {Direction::from_degrees(30, 0), Direction::from_degrees(95, 20)})),
                HasSubstr("direction set 'low': direction 1 (theta 95.000 deg, phi 20.000 deg) "
                          "is below the horizon"));
    EXPECT_THAT(message(DirectionSet("nan", {Direction{NAN, 0}})),
                HasSubstr("direction set 'nan': direction 0 is not finite"));
    EXPECT_THAT(message(DirectionSet::ubo81(), 0),
                HasSubstr("direction set 'ubo81': grid resolution 0 is outside [1, 1024]"));
    EXPECT_THAT(message(DirectionSet::ubo81(), 4096), HasSubstr("outside [1, 1024]"));
}

TEST(AngularInterpolator, CoarseAndFineGridsAgree) {
    // The exported grid's resolution changes neither weights() nor the shader's lookup.
    const AngularInterpolator coarse(DirectionSet::dome151(), 1);
    const AngularInterpolator fine(DirectionSet::dome151(), 256);
    const AngularInterpolator::Tables coarse_tables = coarse.tables(), fine_tables = fine.tables();
    EXPECT_EQ(coarse_tables.cell_offsets.size(), 2u);
    EXPECT_EQ(fine_tables.cell_offsets.size(), 256u * 256 + 1);
    std::mt19937_64 rng(9);
    for (int i = 0; i < 20000; ++i) {
        const Vec3 q = random_query(rng, i);
        ASSERT_LT(max_difference(dense(coarse.weights(q), 151), dense(fine.weights(q), 151)), 1e-6);
        if (i % 10 == 0) {
            const std::vector<double> a = shader_weights(coarse_tables, q);
            const std::vector<double> b = shader_weights(fine_tables, q);
            ASSERT_EQ(a.size(), b.size());
            ASSERT_LT(max_difference(a, b), 1e-5);
        }
    }
    EXPECT_EQ(coarse.fallback_count(), 0);
    EXPECT_EQ(fine.fallback_count(), 0);
}

}  // namespace
}  // namespace btf
