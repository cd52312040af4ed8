// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/parametrization.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <set>

#include "btf/core/angular_interpolator.h"
#include "btf/io/function_source.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/parallel.h"

namespace btf::mlvq {
namespace {

using ::testing::HasSubstr;

Vec3 random_hemisphere(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> uni(0, 1);
    return Direction{std::acos(uni(rng)), 2 * kPi * uni(rng)}.vector();
}

// A unit vector perpendicular to v, uniformly at random.
Vec3 random_tangent(std::mt19937_64& rng, const Vec3& v) {
    std::normal_distribution<double> normal;
    const Vec3 r{normal(rng), normal(rng), normal(rng)};
    return normalize(r - v * dot(r, v));
}

void expect_near(const Vec3& a, const Vec3& b, double tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

// ---- grid --------------------------------------------------------------------------------------

TEST(MlvqGrid, DefaultsAreThePapers) {
    const MlvqGrid g;
    EXPECT_NO_THROW(g.validate());
    EXPECT_EQ(g.samples(), 13552);  // §6: 11 · 11 · 7 · 16
    EXPECT_EQ(g.light_samples(), 121);
    EXPECT_EQ(g.index(15, 6, 10, 10), g.samples() - 1);
    EXPECT_EQ(g.index(0, 0, 1, 0), 11);
    EXPECT_EQ(g.index(0, 1, 0, 0), 121);
    EXPECT_EQ(g.index(1, 0, 0, 0), 847);
}

TEST(MlvqGrid, RejectsBadAxes) {
    auto message = [](MlvqGrid g) { return test::error_of([&] { g.validate(); }); };
    EXPECT_THAT(message({2, 11, 7, 16}), HasSubstr("mlvq grid: n_alpha = 2 is below 3"));
    EXPECT_THAT(message({11, 2, 7, 16}), HasSubstr("mlvq grid: n_beta = 2 is below 3"));
    EXPECT_THAT(message({11, 11, 1, 16}), HasSubstr("mlvq grid: n_theta_v = 1 is below 2"));
    EXPECT_THAT(message({11, 11, 7, 0}), HasSubstr("mlvq grid: n_phi_v = 0 is below 1"));
    EXPECT_THAT(message({11, 11, 7, 2}), HasSubstr("n_phi_v = 2 cannot tell view azimuths"));
    EXPECT_THAT(message({11, 1025, 7, 16}), HasSubstr("n_beta = 1025 is above the limit 1024"));
    EXPECT_THAT(message({1024, 1024, 64, 16}), HasSubstr("samples per texel and channel exceed"));
    EXPECT_NO_THROW((MlvqGrid{3, 3, 2, 1}.validate()));  // isotropic
    EXPECT_NO_THROW((MlvqGrid{3, 3, 2, 3}.validate()));
}

TEST(MlvqGrid, SamplePositions) {
    const MlvqGrid g;
    // α: uniform over the closed range, both horizon slices and the normal's slice included.
    EXPECT_DOUBLE_EQ(g.alpha(0), -kPi / 2);
    EXPECT_DOUBLE_EQ(g.alpha(5), 0);
    EXPECT_DOUBLE_EQ(g.alpha(10), kPi / 2);
    for (int i = 1; i < g.n_alpha; ++i) EXPECT_NEAR(g.alpha(i) - g.alpha(i - 1), kPi / 10, 1e-12);
    // β: the poles exactly, projections onto A–B equidistant, symmetric, dense in the middle.
    EXPECT_EQ(g.sin_beta(0), -1.0);
    EXPECT_EQ(g.sin_beta(10), 1.0);
    EXPECT_EQ(g.beta(10), kPi / 2);
    EXPECT_EQ(g.beta(5), 0.0);
    for (int j = 1; j < g.n_beta; ++j) {
        EXPECT_NEAR(g.sin_beta(j) - g.sin_beta(j - 1), 0.2, 1e-12);
        EXPECT_NEAR(std::sin(g.beta(j)), g.sin_beta(j), 1e-15);
        EXPECT_NEAR(g.beta(j), -g.beta(10 - j), 1e-15);
    }
    EXPECT_LT(g.beta(6) - g.beta(5), g.beta(10) - g.beta(9));
    EXPECT_NEAR(degrees(g.beta(6) - g.beta(5)), 11.537, 1e-3);
    EXPECT_NEAR(degrees(g.beta(10) - g.beta(9)), 36.870, 1e-3);
    // θv: 0 … 90° in 15° steps, landing on every UBO2003 ring.
    for (int k = 0; k < g.n_theta_v; ++k) EXPECT_NEAR(degrees(g.theta_v(k)), 15.0 * k, 1e-12);
    std::set<int> rings;
    for (const Direction& d : DirectionSet::ubo81().directions())
        rings.insert(static_cast<int>(std::lround(d.theta_deg())));
    for (int ring : rings) EXPECT_NEAR(std::fmod(ring, 15.0), 0, 1e-9) << ring;
    // φv: periodic, 2π not repeated.
    EXPECT_EQ(g.phi_v(0), 0.0);
    EXPECT_NEAR(degrees(g.phi_v(15)), 337.5, 1e-12);
}

TEST(MlvqGrid, LightWeightsAreEqualAreaAndCountThePolesOnce) {
    const MlvqGrid g;
    double total = 0, pole_row = 0;
    for (int i = 0; i < g.n_alpha; ++i) {
        for (int j = 0; j < g.n_beta; ++j) total += g.light_weight(i, j);
        pole_row += g.light_weight(i, 0);
    }
    EXPECT_NEAR(total, 2 * kPi, 1e-12);
    EXPECT_NEAR(pole_row, kPi * 0.2 / 2, 1e-12);  // the cap u ≥ 0.9 around the pole
    // Every interior sample stands for the same solid angle (equal-area coordinates).
    EXPECT_NEAR(g.light_weight(3, 4), g.light_weight(5, 5), 1e-15);
    EXPECT_NEAR(g.light_weight(3, 4), kPi / 10 * 0.2, 1e-15);

    // ∫ cos θ dω = π: the trapezoid rule over the grid converges to it.
    auto cosine_integral = [](const MlvqGrid& grid) {
        double sum = 0;
        for (int i = 0; i < grid.n_alpha; ++i)
            for (int j = 0; j < grid.n_beta; ++j)
                sum += grid.light_weight(i, j) *
                       direction_from_onion_u(grid.alpha(i), grid.sin_beta(j), 0.3).z;
        return sum;
    };
    const double coarse = std::abs(cosine_integral(g) - kPi);
    const double fine = std::abs(cosine_integral({101, 101, 2, 1}) - kPi);
    EXPECT_LT(coarse, 0.15);  // 0.13: √(1 − u²) is steep at the poles
    EXPECT_LT(fine, coarse / 20);
}

// ---- mapping -----------------------------------------------------------------------------------

TEST(MlvqMapping, RoundTripOverTheHemisphere) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> uni(0, 1);
    for (int n = 0; n < 20000; ++n) {
        const Vec3 wi = random_hemisphere(rng);
        const double phi_v = 2 * kPi * uni(rng);
        const OnionAngles a = onion_from_direction(wi, phi_v);
        ASSERT_LE(std::abs(a.alpha), kPi / 2);
        ASSERT_LE(std::abs(a.beta), kPi / 2);
        expect_near(direction_from_onion(a, phi_v), wi, 1e-12);

        // The paper's angles: sin β = sin θi sin(φi − φv), cos α cos β = cos θi, α < 0 on the
        // viewer's side.
        const Direction d = Direction::from_vector(wi);
        const double delta = d.phi - phi_v;
        EXPECT_NEAR(std::sin(a.beta), std::sin(d.theta) * std::sin(delta), 1e-12);
        EXPECT_NEAR(std::cos(a.alpha) * std::cos(a.beta), std::cos(d.theta), 1e-12);
        if (std::abs(std::cos(delta)) > 1e-6 && d.theta > 1e-6) {
            EXPECT_EQ((a.alpha < 0), (std::cos(delta) > 0));
        }
    }
    // And the other way, away from the poles where α is undefined.
    for (int n = 0; n < 20000; ++n) {
        const OnionAngles a{kPi * (uni(rng) - 0.5), (kPi - 2e-3) * (uni(rng) - 0.5)};
        const double phi_v = 2 * kPi * uni(rng);
        const Vec3 wi = direction_from_onion(a, phi_v);
        EXPECT_NEAR(length(wi), 1, 1e-14);
        EXPECT_GE(wi.z, -1e-15);
        const OnionAngles back = onion_from_direction(wi, phi_v);
        EXPECT_NEAR(back.alpha, a.alpha, 1e-9);
        EXPECT_NEAR(back.beta, a.beta, 1e-9);
        // √(1 − u²) loses a few bits near the poles.
        expect_near(direction_from_onion_u(a.alpha, std::sin(a.beta), phi_v), wi, 1e-12);
    }
}

// The default frame (what lookup arrays hold before a lookup) is the frame of φv = 0, bit for bit.
TEST(MlvqMapping, DefaultFrameIsAzimuthZero) {
    const OnionFrame d, zero(0.0);
    for (const auto& [a, b] : {std::pair{d.e_beta, zero.e_beta}, std::pair{d.e_alpha, zero.e_alpha},
                               std::pair{d.n, zero.n}})
        EXPECT_EQ(std::memcmp(&a, &b, sizeof(Vec3)), 0) << a.x << " " << a.y << " " << a.z;
}

TEST(MlvqMapping, SpecialDirections) {
    const double phi_v = radians(30), theta_v = radians(40);
    const OnionFrame f(phi_v);
    expect_near(cross(f.e_beta, f.e_alpha), f.n, 1e-15);  // right-handed
    // The normal is the middle of the middle slice.
    const OnionAngles top = onion_from_direction({0, 0, 1}, phi_v);
    EXPECT_EQ(top.alpha, 0.0);
    EXPECT_EQ(top.beta, 0.0);
    // The mirror direction and the view itself lie in the plane β = 0, at α = ±θv.
    const OnionAngles mirror =
        onion_from_direction(Direction{theta_v, phi_v + kPi}.vector(), phi_v);
    EXPECT_NEAR(mirror.alpha, theta_v, 1e-12);
    EXPECT_NEAR(mirror.beta, 0, 1e-12);
    const OnionAngles retro = onion_from_direction(Direction{theta_v, phi_v}.vector(), phi_v);
    EXPECT_NEAR(retro.alpha, -theta_v, 1e-12);
    EXPECT_NEAR(retro.beta, 0, 1e-12);
    // The poles A and B: perpendicular to the view azimuth, on the horizon, for every α.
    expect_near(f.e_beta, Direction{kPi / 2, phi_v + kPi / 2}.vector(), 1e-15);
    for (int i = 0; i <= 10; ++i) {
        const double alpha = kPi * (i / 10.0 - 0.5);
        EXPECT_EQ(direction_from_onion_u(alpha, 1, phi_v), f.e_beta);
        EXPECT_EQ(direction_from_onion_u(alpha, -1, phi_v), -f.e_beta);
    }
    EXPECT_NEAR(onion_from_direction(f.e_beta, phi_v).beta, kPi / 2, 1e-7);
    EXPECT_NEAR(onion_from_direction(-f.e_beta, phi_v).beta, -kPi / 2, 1e-7);
    // The rim: the slices α = ±π/2 are the horizon, on the viewer's side for −π/2.
    for (int j = 0; j <= 10; ++j) {
        const double u = j / 5.0 - 1;
        EXPECT_NEAR(direction_from_onion_u(kPi / 2, u, phi_v).z, 0, 1e-15);
        EXPECT_NEAR(direction_from_onion_u(-kPi / 2, u, phi_v).z, 0, 1e-15);
    }
    EXPECT_NEAR(onion_from_direction(Direction{kPi / 2, phi_v}.vector(), phi_v).alpha, -kPi / 2,
                1e-12);
    EXPECT_NEAR(onion_from_direction(Direction{kPi / 2, phi_v + kPi}.vector(), phi_v).alpha,
                kPi / 2, 1e-12);
    // Below the horizon: clamped onto it at its azimuth; no direction at all: +x on the horizon.
    const OnionAngles below = onion_from_direction({0.3, -0.4, -0.5}, phi_v);
    const OnionAngles horizon = onion_from_direction({0.6, -0.8, 0}, phi_v);
    EXPECT_NEAR(below.alpha, horizon.alpha, 1e-15);
    EXPECT_NEAR(below.beta, horizon.beta, 1e-15);
    for (const Vec3& none : {Vec3{0, 0, 0}, Vec3{0, 0, -1}, Vec3{NAN, 0, 1}}) {
        const OnionAngles a = onion_from_direction(none, phi_v);
        const OnionAngles x = onion_from_direction({1, 0, 0}, phi_v);
        EXPECT_EQ(a.alpha, x.alpha);
        EXPECT_EQ(a.beta, x.beta);
    }
    // Length does not matter.
    const OnionAngles big = onion_from_direction(Vec3{1, 2, 3} * 1e150, phi_v);
    const OnionAngles small = onion_from_direction(Vec3{1, 2, 3} * 1e-150, phi_v);
    EXPECT_NEAR(big.alpha, small.alpha, 1e-15);
    EXPECT_NEAR(big.beta, small.beta, 1e-15);
}

TEST(MlvqMapping, ViewAndLightRoundTrip) {
    std::mt19937_64 rng(11);
    for (int n = 0; n < 5000; ++n) {
        const Vec3 wi = random_hemisphere(rng), wo = random_hemisphere(rng);
        const MlvqCoordinates c = to_mlvq(wi * 3, wo * 0.5);
        EXPECT_GE(c.phi_v, 0);
        EXPECT_LT(c.phi_v, 2 * kPi);
        Vec3 wi2, wo2;
        from_mlvq(c, wi2, wo2);
        expect_near(wi2, wi, 1e-12);
        expect_near(wo2, wo, 1e-12);
    }
    // A view along the normal has azimuth 0.
    const MlvqCoordinates c = to_mlvq({0.5, 0.5, 0.7}, {0, 0, 2});
    EXPECT_EQ(c.theta_v, 0.0);
    EXPECT_EQ(c.phi_v, 0.0);
    const OnionAngles a = onion_from_direction({0.5, 0.5, 0.7}, 0);
    EXPECT_DOUBLE_EQ(c.alpha, a.alpha);
    EXPECT_DOUBLE_EQ(c.beta, a.beta);
}

// ---- lookup ------------------------------------------------------------------------------------

// Unit (ωi, ωo) of grid sample (m, k, i, j).
void sample_directions(const MlvqGrid& g, int m, int k, int i, int j, Vec3& wi, Vec3& wo) {
    wo = Direction{g.theta_v(k), g.phi_v(m)}.vector();
    wi = direction_from_onion_u(g.alpha(i), g.sin_beta(j), g.phi_v(m));
}

float weight_of(const AxisWeights& w, int index) {
    float sum = 0;
    for (int q = 0; q < 2; ++q)
        if (w.index[q] == index) sum += w.weight[q];
    return sum;
}

// Random grid values of one channel that agree at the light poles (one direction per view).
std::vector<float> pole_consistent_values(const MlvqGrid& g, uint64_t seed) {
    std::vector<float> v(g.samples());
    for (int64_t s = 0; s < g.samples(); ++s) v[s] = test::hash01(seed, s, 0, 0);
    for (int m = 0; m < g.n_phi_v; ++m)
        for (int k = 0; k < g.n_theta_v; ++k)
            for (int i = 0; i < g.n_alpha; ++i) {
                v[g.index(m, k, i, 0)] = v[g.index(m, k, 0, 0)];
                v[g.index(m, k, i, g.n_beta - 1)] = v[g.index(m, k, 0, g.n_beta - 1)];
            }
    return v;
}

TEST(MlvqLookup, WeightsArePartitionsOfUnity) {
    const MlvqGrid g;
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> uni(-1, 1);
    for (int n = 0; n < 20000; ++n) {
        // Any vectors: below the horizon, not unit, sometimes degenerate.
        Vec3 wi{uni(rng), uni(rng), uni(rng)}, wo{uni(rng), uni(rng), uni(rng)};
        if (n % 100 == 0) wi = {0, 0, 0};
        if (n % 100 == 1) wo = {0, 0, -1};
        const MlvqWeights w = lookup(g, wi, wo);
        const std::pair<const AxisWeights*, int> axes[] = {{&w.alpha, g.n_alpha},
                                                           {&w.beta, g.n_beta},
                                                           {&w.theta_v, g.n_theta_v},
                                                           {&w.phi_v, g.n_phi_v}};
        for (const auto& [axis, size] : axes) {
            EXPECT_NEAR(axis->weight[0] + axis->weight[1], 1, 1e-6);
            for (int q = 0; q < 2; ++q) {
                EXPECT_GE(axis->weight[q], 0);
                EXPECT_GE(axis->index[q], 0);
                EXPECT_LT(axis->index[q], size);
            }
        }
        EXPECT_EQ(w.phi_v.index[1], (w.phi_v.index[0] + 1) % g.n_phi_v);
        // The vector form (fast atan2) equals the coordinate form (libm) to float precision.
        const MlvqWeights c = lookup(g, to_mlvq(wi, wo));
        for (int q = 0; q < 2; ++q) {
            EXPECT_NEAR(c.alpha.weight[q], w.alpha.weight[q], 1e-6);
            EXPECT_NEAR(c.beta.weight[q], w.beta.weight[q], 1e-6);
            EXPECT_NEAR(c.theta_v.weight[q], w.theta_v.weight[q], 1e-6);
            EXPECT_NEAR(c.phi_v.weight[q], w.phi_v.weight[q], 1e-6);
        }
        float total = 0;
        for (int c = 0; c < 16; ++c) total += w.weight(c & 1, c >> 1 & 1, c >> 2 & 1, c >> 3);
        EXPECT_NEAR(total, 1, 1e-5);
    }
}

TEST(MlvqLookup, BatchEqualsOneByOne) {
    const MlvqGrid g;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> uni(-1, 1);
    // Random vectors mixed with every special case of the scalar path, in every lane position.
    const std::vector<Vec3> special = {{0, 0, 0},         {0, 0, -1},     {NAN, 0, 1},
                                       {0, INFINITY, 1},  {0, 0, 1},      {0, 0, NAN},
                                       {-0.0, 0.0, 1},    {1e-300, 0, 0}, {-1, -0.0, 0},
                                       {1e300, 1e300, 1}, {0.6, -0.8, 0}, {0, 1, 0}};
    std::vector<Vec3> wi, wo;
    for (int n = 0; n < 4000; ++n) {
        wi.push_back({uni(rng), uni(rng), uni(rng)});
        wo.push_back({uni(rng), uni(rng), uni(rng)});
        if (n % 7 == 0) wi.back() = special[size_t(n / 7) % special.size()];
        if (n % 5 == 0) wo.back() = special[size_t(n / 5) % special.size()];
    }
    // The light at a pole of the view's frame: perpendicular to the view azimuth on the horizon.
    for (int n = 0; n < 8; ++n) {
        const double phi = radians(45.0 * n);
        wo.push_back(Direction{radians(50), phi}.vector());
        wi.push_back(Direction{kPi / 2, phi + kPi / 2}.vector());
    }
    wi.push_back({0.1, 0.2, 0.9});  // an odd count leaves a tail for the scalar loop
    wo.push_back({0.3, -0.2, 0.8});
    std::vector<MlvqWeights> batch(wi.size());
    lookup(g, wi.data(), wo.data(), wi.size(), batch.data());
    // Values of a function on the hemisphere: the poles (u = ±1) are one direction for all α
    // (where α is undefined and the two paths' roundings may pick different slices).
    std::vector<float> values(size_t(g.samples()));
    for (float& v : values) v = float(uni(rng));
    for (int p = 0; p < g.n_phi_v; ++p)
        for (int t = 0; t < g.n_theta_v; ++t)
            for (int i = 0; i < g.n_alpha; ++i)
                for (int j : {0, g.n_beta - 1})
                    values[size_t(g.index(p, t, i, j))] = values[size_t(g.index(p, t, 0, j))];
    for (size_t k = 0; k < wi.size(); ++k) {
        const MlvqWeights one = lookup(g, wi[k], wo[k]);
        EXPECT_NEAR(reconstruct(g, batch[k], values.data()), reconstruct(g, one, values.data()),
                    1e-5)
            << "query " << k;
    }
}

// lookup_views() and lookup_lights(): a direction's lookup is the same, bit for bit, alone
// (n = 1) as at any place of a batch (what the stochastic filter's batches rely on), and it is
// lookup()'s up to the rounding of the vector path, special directions included.
TEST(MlvqLookup, ViewAndLightBatchesDoNotDependOnThePlace) {
    const MlvqGrid g;
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> uni(-1, 1);
    const std::vector<Vec3> special = {{0, 0, 0}, {0, 0, -1},     {NAN, 0, 1},
                                       {0, 0, 1}, {-0.0, 0.0, 1}, {-1, -0.0, 0},
                                       {0, 1, 0}, {0, 0, NAN},    {1e300, 1e300, 1}};
    std::vector<Vec3> wi, wo;
    for (int n = 0; n < 1001; ++n) {  // a partial last group
        wi.push_back({uni(rng), uni(rng), uni(rng)});
        wo.push_back({uni(rng), uni(rng), uni(rng)});
        if (n % 7 == 0) wi.back() = special[size_t(n / 7) % special.size()];
        if (n % 5 == 0) wo.back() = special[size_t(n / 5) % special.size()];
        if (n % 11 == 0) {  // the light at a pole of the view's frame
            const double phi = uni(rng) * kPi;
            wo.back() = Direction{radians(40), phi}.vector();
            wi.back() = Direction{kPi / 2, phi - kPi / 2}.vector();
        }
    }
    std::vector<ViewLookup> views(wo.size());
    std::vector<MlvqWeights> lights(wi.size());
    lookup_views(g, wo.data(), wo.size(), views.data());
    lookup_lights(g, wi.data(), views.data(), wi.size(), lights.data());
    std::vector<float> values(size_t(g.samples()));
    for (float& v : values) v = float(uni(rng));
    for (int p = 0; p < g.n_phi_v; ++p)
        for (int t = 0; t < g.n_theta_v; ++t)
            for (int i = 0; i < g.n_alpha; ++i)
                for (int j : {0, g.n_beta - 1})
                    values[size_t(g.index(p, t, i, j))] = values[size_t(g.index(p, t, 0, j))];
    auto same = [](const AxisWeights& a, const AxisWeights& b) {
        return a.index == b.index && a.weight == b.weight;
    };
    for (size_t k = 0; k < wi.size(); ++k) {
        ViewLookup view;
        MlvqWeights light;
        lookup_views(g, &wo[k], 1, &view);
        lookup_lights(g, &wi[k], &view, 1, &light);
        EXPECT_TRUE(same(view.weights.theta_v, views[k].weights.theta_v)) << k;
        EXPECT_TRUE(same(view.weights.phi_v, views[k].weights.phi_v)) << k;
        EXPECT_EQ(view.frame.e_beta, views[k].frame.e_beta) << k;
        EXPECT_TRUE(same(light.alpha, lights[k].alpha)) << k;
        EXPECT_TRUE(same(light.beta, lights[k].beta)) << k;
        MlvqWeights w = views[k].weights;
        w.alpha = lights[k].alpha;
        w.beta = lights[k].beta;
        const MlvqWeights scalar = lookup(g, wi[k], wo[k]);
        EXPECT_NEAR(reconstruct(g, w, values.data()), reconstruct(g, scalar, values.data()), 1e-5)
            << "query " << k;
        const ViewLookup scalar_view = lookup_view(g, wo[k]);
        expect_near(views[k].frame.e_beta, scalar_view.frame.e_beta, 1e-12);
    }
}

TEST(MlvqMapping, SinCosOfTheSlices) {
    double worst = 0;
    for (int i = 0; i <= 100000; ++i) {
        const double a = -kPi / 2 + kPi * i / 100000;
        double s, c;
        sin_cos_half_pi(a, s, c);
        worst = std::max({worst, std::abs(s - std::sin(a)), std::abs(c - std::cos(a))});
    }
    EXPECT_LT(worst, 5e-16);
    double s, c;
    sin_cos_half_pi(3.0, s, c);  // outside: libm
    EXPECT_EQ(s, std::sin(3.0));
    EXPECT_EQ(c, std::cos(3.0));
}

TEST(MlvqLookup, SampleDirectionsHaveWeightOneOnThemselves) {
    for (const MlvqGrid& g : {MlvqGrid{}, MlvqGrid{5, 7, 4, 3}, MlvqGrid{4, 3, 2, 1}}) {
        const std::vector<float> values = pole_consistent_values(g, 5);
        for (int m = 0; m < g.n_phi_v; ++m)
            for (int k = 0; k < g.n_theta_v; ++k) {
                // A view along the normal has azimuth 0: the other azimuths of θv = 0 are reached
                // only as limits (see the header).
                if (k == 0 && m != 0) continue;
                for (int i = 0; i < g.n_alpha; ++i)
                    for (int j = 0; j < g.n_beta; ++j) {
                        Vec3 wi, wo;
                        sample_directions(g, m, k, i, j, wi, wo);
                        const MlvqWeights w = lookup(g, wi, wo);
                        EXPECT_NEAR(weight_of(w.phi_v, m), 1, 1e-6);
                        EXPECT_NEAR(weight_of(w.theta_v, k), 1, 1e-6);
                        EXPECT_NEAR(weight_of(w.beta, j), 1, 1e-6);
                        const bool pole = j == 0 || j == g.n_beta - 1;  // α is undefined there
                        if (!pole) {
                            EXPECT_NEAR(weight_of(w.alpha, i), 1, 1e-6);
                        }
                        const int64_t s = g.index(m, k, i, j);
                        EXPECT_NEAR(reconstruct(g, w, values.data()), values[s], 1e-6);
                    }
            }
    }
}

TEST(MlvqLookup, ReconstructionIsContinuous) {
    const MlvqGrid g;
    const std::vector<float> values = pole_consistent_values(g, 9);
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<double> uni(0, 1);
    const double step = 1e-7;
    double worst_value = 0, worst_weight = 0;
    for (int n = 0; n < 50000; ++n) {
        Vec3 wo = random_hemisphere(rng);
        if (Direction::from_vector(wo).theta < radians(5)) continue;  // the view pole, see header
        Vec3 wi = random_hemisphere(rng);
        const OnionFrame f(Direction::from_vector(wo).phi);
        switch (n % 5) {
            case 0:  // near a light pole, where the α weights turn fast
                wi = normalize(f.e_beta * (n % 10 ? 1 : -1) +
                               random_tangent(rng, f.e_beta) * 1e-4 * uni(rng));
                break;
            case 1:  // near the view azimuth's wrap at φv = 0
                wo = Direction{std::acos(uni(rng)) * 0.9 + 0.1, 1e-8 * (uni(rng) - 0.5)}.vector();
                break;
            case 2:  // near the horizon
                wi = Direction{kPi / 2 - 1e-6 * uni(rng), 2 * kPi * uni(rng)}.vector();
                break;
            default:
                break;
        }
        const OnionFrame frame(Direction::from_vector(wo).phi);
        const Vec3 wi2 = normalize(wi + random_tangent(rng, wi) * step);
        const Vec3 wo2 = normalize(wo + random_tangent(rng, wo) * step);
        const MlvqWeights a = lookup(g, wi, wo), b = lookup(g, wi2, wo2);
        worst_value = std::max<double>(worst_value, std::abs(reconstruct(g, a, values.data()) -
                                                             reconstruct(g, b, values.data())));
        // The weights themselves move little too, away from the light poles.
        if (std::abs(dot(wi, frame.e_beta)) < 0.99) {
            std::map<int64_t, float> wa, wb;
            for (int c = 0; c < 16; ++c) {
                const int ca = c & 1, cb = c >> 1 & 1, ct = c >> 2 & 1, cp = c >> 3;
                wa[a.sample(g, ca, cb, ct, cp)] += a.weight(ca, cb, ct, cp);
                wb[b.sample(g, ca, cb, ct, cp)] += b.weight(ca, cb, ct, cp);
            }
            for (const auto& [s, w] : wa)
                worst_weight = std::max<double>(worst_weight, std::abs(w - wb[s]));
            for (const auto& [s, w] : wb)
                worst_weight = std::max<double>(worst_weight, std::abs(w - wa[s]));
        }
    }
    // A change of 1e-7 rad moves the weights by ~1e-6 (grid steps are ~0.2 rad; φv and the onion
    // frame turn 1 / sin θv faster near the view pole).
    EXPECT_LT(worst_value, 5e-5);
    EXPECT_LT(worst_weight, 5e-5);

    // The reconstruction also varies: a jump detector that is not blind.
    const MlvqWeights far1 = lookup(g, Direction{0.3, 1}.vector(), Direction{0.5, 2}.vector());
    const MlvqWeights far2 = lookup(g, Direction{0.6, 1}.vector(), Direction{0.5, 2}.vector());
    EXPECT_GT(std::abs(reconstruct(g, far1, values.data()) - reconstruct(g, far2, values.data())),
              1e-3);
}

TEST(MlvqLookup, IsotropicGridIgnoresTheViewAzimuth) {
    const MlvqGrid g{11, 11, 7, 1};
    const std::vector<float> values = pole_consistent_values(g, 13);
    std::mt19937_64 rng(5);
    for (int n = 0; n < 1000; ++n) {
        const Direction di = Direction::from_vector(random_hemisphere(rng));
        const Direction dv = Direction::from_vector(random_hemisphere(rng));
        const double turn = 2 * kPi * test::hash01(n, 1, 2, 3);
        const MlvqWeights a = lookup(g, di.vector(), dv.vector());
        const MlvqWeights b = lookup(g, Direction{di.theta, di.phi + turn}.vector(),
                                     Direction{dv.theta, dv.phi + turn}.vector());
        EXPECT_EQ(a.phi_v.index[0], 0);
        EXPECT_EQ(a.phi_v.weight[0], 1.0f);
        EXPECT_NEAR(reconstruct(g, a, values.data()), reconstruct(g, b, values.data()), 1e-5);
    }
}

// ---- resampling --------------------------------------------------------------------------------

// Rings of directions every `step` degrees of θ up to `max_deg`, about `step` apart along each
// ring (a synthetic measurement dome of a chosen density).
DirectionSet dome(const std::string& name, double step, double max_deg) {
    std::vector<Direction> dirs{{0, 0}};
    for (double t = step; t <= max_deg + 1e-9; t += step) {
        const int count =
            std::max(6, static_cast<int>(std::lround(360 * std::sin(radians(t)) / step)));
        for (int q = 0; q < count; ++q)
            dirs.push_back(Direction::from_degrees(t, 360.0 * q / count));
    }
    return DirectionSet(name, dirs);
}

// A smooth function of (ωi, ωo), different per channel and texel.
Rgb smooth(const Vec3& wi, const Vec3& wo, int x, int y) {
    const Vec3 h = normalize(wi + wo);
    const double base = 0.3 + 0.3 * wi.z + 0.15 * wo.z + 0.2 * h.z * h.z + 0.1 * wi.x * wo.y;
    const double t = 1 + 0.1 * x - 0.05 * y;
    return {float(base * t), float(base * t * 0.8 + 0.05), float(base * t * 0.6 + 0.1 * wi.y)};
}

std::unique_ptr<FunctionSource> smooth_source(const Sampling& sampling, int width, int height) {
    return std::make_unique<FunctionSource>(
        sampling, width, height, [sampling](int v, int l, int x, int y) {
            return smooth(sampling.lights.vector(l), sampling.views.vector(v), x, y);
        });
}

TEST(MlvqResampler, TableIsConvexAndPolesAgree) {
    const MlvqGrid g;
    const Sampling ubo{DirectionSet::ubo81(), DirectionSet::ubo81()};
    const Resampler r(g, ubo);
    EXPECT_EQ(r.samples(), 13552);
    for (int64_t s = 0; s < r.samples(); ++s) {
        const auto terms = r.terms(s);
        ASSERT_GE(terms.size(), 1u);
        ASSERT_LE(terms.size(), 9u);
        double sum = 0;
        for (size_t e = 0; e < terms.size(); ++e) {
            EXPECT_GT(terms[e].weight, 0);
            EXPECT_LT(terms[e].image, 81 * 81);
            if (e) {
                EXPECT_LT(terms[e - 1].image, terms[e].image);
            }
            sum += terms[e].weight;
        }
        EXPECT_NEAR(sum, 1, 1e-6);
    }
    // The poles: the same direction, the same terms, in every slice.
    for (int m = 0; m < g.n_phi_v; ++m)
        for (int k = 0; k < g.n_theta_v; ++k)
            for (int j : {0, g.n_beta - 1})
                for (int i = 1; i < g.n_alpha; ++i) {
                    const auto a = r.terms(g.index(m, k, 0, j)), b = r.terms(g.index(m, k, i, j));
                    ASSERT_EQ(a.size(), b.size());
                    for (size_t e = 0; e < a.size(); ++e) {
                        EXPECT_EQ(a[e].image, b[e].image);
                        EXPECT_EQ(a[e].weight, b[e].weight);
                    }
                }
    // A grid sample on a measured pair takes that image alone: view θ = 15°, φ = 0 (UBO view 1)
    // and the light along the normal (UBO light 0).
    const auto exact = r.terms(g.index(0, 1, 5, 5));
    float best = 0;
    int best_image = -1;
    for (const auto& t : exact)
        if (t.weight > best) best = t.weight, best_image = t.image;
    EXPECT_EQ(best_image, 1 * 81 + 0);
    EXPECT_EQ(exact.size(), 1u);
    EXPECT_EQ(best, 1.0f);
}

TEST(MlvqResampler, ConstantSourceResamplesExactly) {
    const Sampling ubo{DirectionSet::ubo81(), DirectionSet::ubo81()};
    const FunctionSource source(ubo, 3, 2, [](int, int, int x, int y) {
        return Rgb{0.2f + 0.1f * x, 0.5f, 0.8f - 0.3f * y};
    });
    const SourceTexels raw = read_rows(source, 0, 2);
    const Resampler r(MlvqGrid{}, ubo);
    const std::vector<float> f = r.resample(raw);
    ASSERT_EQ(f.size(), size_t(6) * 3 * r.samples());
    for (int t = 0; t < 6; ++t) {
        const Rgb c = source.value(0, 0, t % 3, t / 3);
        const float expected[3] = {c.r, c.g, c.b};
        for (int ch = 0; ch < 3; ++ch)
            for (int64_t s = 0; s < r.samples(); ++s)
                ASSERT_NEAR(f[(t * 3 + ch) * r.samples() + s], expected[ch], 1e-6)
                    << "texel " << t << " channel " << ch << " sample " << s;
    }
}

// Largest |F_x − f| over the grid samples whose light and view lie within `max_theta` of the
// normal (beyond the source's outermost ring the interpolator projects onto that ring).
double smooth_error(const Sampling& sampling, const MlvqGrid& g, double max_theta) {
    const int width = 2, height = 2;
    const auto source = smooth_source(sampling, width, height);
    const SourceTexels raw = read_rows(*source, 0, height);
    const Resampler r(g, sampling);
    const std::vector<float> f = r.resample(raw);
    double worst = 0;
    for (int m = 0; m < g.n_phi_v; ++m)
        for (int k = 0; k < g.n_theta_v; ++k)
            for (int i = 0; i < g.n_alpha; ++i)
                for (int j = 0; j < g.n_beta; ++j) {
                    Vec3 wi, wo;
                    sample_directions(g, m, k, i, j, wi, wo);
                    if (wi.z < std::cos(max_theta) || wo.z < std::cos(max_theta)) continue;
                    const int64_t s = g.index(m, k, i, j);
                    for (int t = 0; t < width * height; ++t) {
                        const Rgb e = smooth(wi, wo, t % width, t / width);
                        const float expected[3] = {e.r, e.g, e.b};
                        for (int c = 0; c < 3; ++c)
                            worst = std::max(
                                worst,
                                std::abs(double(f[(t * 3 + c) * r.samples() + s]) - expected[c]));
                    }
                }
    return worst;
}

TEST(MlvqResampler, SmoothSourceResamplesToItsFunction) {
    const MlvqGrid g;
    const DirectionSet coarse = dome("dome15", 15, 75), fine = dome("dome7.5", 7.5, 75);
    const double e_ubo =
        smooth_error({DirectionSet::ubo81(), DirectionSet::ubo81()}, g, radians(75));
    const double e_coarse = smooth_error({coarse, coarse}, g, radians(75));
    const double e_fine = smooth_error({fine, fine}, g, radians(75));
    // Values are ~0.3 … 1.1; piecewise-linear interpolation over 15° triangles is within a few
    // per cent (measured: 0.021 on ubo81, 0.017 on the 15° dome).
    EXPECT_LT(e_ubo, 0.03);
    EXPECT_LT(e_coarse, 0.03);
    EXPECT_LT(e_fine, e_coarse / 2);
    // And second order: halving the spacing divides the error by about 4 (measured 3.9 inside
    // 60°; up to 75° the projection onto the outer ring's edges adds a little).
    const double c60 = smooth_error({coarse, coarse}, g, radians(60));
    const double f60 = smooth_error({fine, fine}, g, radians(60));
    EXPECT_LT(f60, c60 / 3.3);
    EXPECT_GT(f60, 0);
}

TEST(MlvqResampler, MatchesTheAngularInterpolatorEverywhere) {
    // Independent path: blend the source's values with AngularInterpolator weights directly.
    const Sampling sampling = test::ubo_subset(14, 12);
    const int width = 7, height = 5;  // 35 texels: four whole tiles and a partial one
    const FunctionSource source(sampling, width, height, [](int v, int l, int x, int y) {
        return Rgb{test::hash01(v, l, x, y), test::hash01(v, l, x, y + 100),
                   test::hash01(v, l, x + 100, y)};
    });
    const MlvqGrid g{5, 7, 4, 6};
    const Resampler r(g, sampling);
    const SourceTexels raw = read_rows(source, 0, height);
    const std::vector<float> f = r.resample(raw);
    const AngularInterpolator views(sampling.views), lights(sampling.lights);
    for (int m = 0; m < g.n_phi_v; ++m)
        for (int k = 0; k < g.n_theta_v; ++k)
            for (int i = 0; i < g.n_alpha; ++i)
                for (int j = 0; j < g.n_beta; ++j) {
                    Vec3 wi, wo;
                    sample_directions(g, m, k, i, j, wi, wo);
                    const AngularWeights vw = views.weights(wo), lw = lights.weights(wi);
                    const int64_t s = g.index(m, k, i, j);
                    for (int t = 0; t < width * height; ++t) {
                        double e[3] = {0, 0, 0};
                        for (int a = 0; a < vw.count; ++a)
                            for (int b = 0; b < lw.count; ++b) {
                                const Rgb v =
                                    source.value(vw.index[a], lw.index[b], t % width, t / width);
                                const double w = double(vw.weight[a]) * lw.weight[b];
                                e[0] += w * v.r, e[1] += w * v.g, e[2] += w * v.b;
                            }
                        for (int c = 0; c < 3; ++c)
                            ASSERT_NEAR(f[(t * 3 + c) * r.samples() + s], e[c], 1e-5)
                                << "sample " << s << " texel " << t;
                    }
                }
    // A batch equals texel-by-texel resampling, and the parallel whole equals both, up to the
    // rounding of the vectorized tile path against the scalar one (the compiler may fuse their
    // multiply-adds differently).
    std::vector<float> one(3 * r.samples()), batch(size_t(20) * 3 * r.samples());
    r.resample(raw, 9, 20, batch.data());
    for (int t = 9; t < 29; ++t) {
        r.resample(raw, t, 1, one.data());
        for (int64_t q = 0; q < 3 * r.samples(); ++q) {
            ASSERT_NEAR(one[q], batch[(t - 9) * 3 * r.samples() + q], 1e-6f * std::abs(one[q]));
            ASSERT_NEAR(one[q], f[t * 3 * r.samples() + q], 1e-6f * std::abs(one[q]));
        }
    }
    // The parallel whole is the same for any thread count.
    {
        ThreadLimit limit(1);
        EXPECT_EQ(r.resample(raw), f);
    }
}

TEST(MlvqResampler, ReadRowsAndErrors) {
    const Sampling sampling = test::five_views_four_lights();
    const FunctionSource source(sampling, 3, 4, [](int v, int l, int x, int y) {
        return Rgb{float(v), float(l), float(10 * y + x)};
    });
    const SourceTexels raw = read_rows(source, 1, 2);
    EXPECT_EQ(raw.views(), 5);
    EXPECT_EQ(raw.lights(), 4);
    EXPECT_EQ(raw.texels(), 6);
    for (int v = 0; v < 5; ++v)
        for (int l = 0; l < 4; ++l)
            for (int t = 0; t < 6; ++t) {
                EXPECT_EQ(raw.value(v, l, 0, t), float(v));
                EXPECT_EQ(raw.value(v, l, 1, t), float(l));
                EXPECT_EQ(raw.value(v, l, 2, t), float(10 * (1 + t / 3) + t % 3));
            }
    EXPECT_EQ(raw.bytes(), SourceTexels::bytes(5, 4, 6));
    EXPECT_EQ(raw.bytes(), 5 * 4 * 3 * SourceTexels::kTile * 4);  // one tile, padded
    // Texels set by hand resample like texels read from the source.
    SourceTexels copy(5, 4, 6);
    for (int v = 0; v < 5; ++v)
        for (int l = 0; l < 4; ++l)
            for (int c = 0; c < 3; ++c)
                for (int t = 0; t < 6; ++t) copy.at(v, l, c, t) = raw.value(v, l, c, t);
    const Resampler small(MlvqGrid{3, 3, 2, 3}, sampling);
    EXPECT_EQ(small.resample(copy), small.resample(raw));

    EXPECT_THAT(test::error_of([&] { read_rows(source, 3, 2); }),
                HasSubstr("function: texel rows 3 to 4 are outside the image's 4 rows"));
    EXPECT_THAT(test::error_of([&] { read_rows(source, 0, 0); }), HasSubstr("outside"));

    std::vector<float> out(3 * small.samples() * 6);
    EXPECT_THAT(test::error_of([&] { small.resample(raw, 4, 3, out.data()); }),
                HasSubstr("texels 4 to 6 are outside the 6 given"));
    EXPECT_THAT(test::error_of([&] { small.resample(raw, std::span<float>(out).first(5)); }),
                HasSubstr("5 output values for 6 texels"));
    const Resampler other(MlvqGrid{3, 3, 2, 3}, test::ubo_subset(3, 4));
    EXPECT_THAT(test::error_of([&] { other.resample(raw); }),
                HasSubstr("texels of 5 views x 4 lights given to a resampler of 3 x 4"));
    EXPECT_THAT(test::error_of([&] {
                    Resampler bad(MlvqGrid{11, 11, 7, 2}, sampling);
                }),
                HasSubstr("n_phi_v = 2"));
}

}  // namespace
}  // namespace btf::mlvq
