// SPDX-License-Identifier: MIT
// The renderer against what can be known: analytic radiance of a Lambertian BTF under delta
// lights, the white furnace, agreement of the MIS, light-only and material-only estimators, the
// orientation of the BTF's local frame on every shape, surface sampling densities, determinism,
// and the scene file's errors.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

#include "btf/core/btf_lookup.h"
#include "btf/render/integrator.h"
#include "btf/render/renderer.h"
#include "btf/render/scene_file.h"
#include "btf/testing/function_material.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::render {
namespace {

std::shared_ptr<const Material> lambertian(float rho) {
    return std::make_shared<test::FunctionMaterial>(test::lambertian_material({rho, rho, rho}));
}

SceneObject object_of(TriangleMesh mesh, std::shared_ptr<const Surface> surface) {
    SceneObject o;
    o.name = "test object";
    o.mesh = std::move(mesh);
    o.surface = std::move(surface);
    return o;
}

Camera looking_down(int size) {
    Camera c;
    c.position = {0, 3, 0};
    c.look_at = {0, 0, 0};
    c.up = {0, 0, -1};
    c.fov = 20;
    c.width = c.height = size;
    return c;
}

double mean_channel(const Image& image, int c) {
    double sum = 0;
    for (int y = 0; y < image.height(); ++y)
        for (int x = 0; x < image.width(); ++x) sum += image.at(x, y, c);
    return sum / double(image.num_pixels());
}

TEST(Render, LambertianPlaneUnderDirectionalAndPointLight) {
    const float rho = 0.6f;
    const double theta = radians(35);
    const Rgb E = {2, 3, 4};
    Scene scene;
    scene.camera = looking_down(8);
    scene.add_object(object_of(make_plane(4, 4), std::make_shared<BtfSurface>(lambertian(rho))));
    scene.add_light(
        std::make_shared<DirectionalLight>(Vec3{std::sin(theta), std::cos(theta), 0}, E));
    scene.commit();
    RenderOptions options;
    options.spp = 2;
    options.integrator.max_depth = 1;
    const RenderResult r = render(scene, options);
    // L = ρ/π · E · cos θ at every pixel, no Monte Carlo error (a delta light, a uniform plane).
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            EXPECT_NEAR(r.color.at(x, y, 0), rho / kPi * E.r * std::cos(theta), 1e-5);
            EXPECT_NEAR(r.color.at(x, y, 2), rho / kPi * E.b * std::cos(theta), 1e-5);
        }

    // A point light of intensity I at height h above the plane's centre: L = ρ/π · I/h² there.
    Scene point;
    point.camera = looking_down(9);
    point.camera.fov = 1;  // the centre pixel's footprint is tiny
    point.add_object(object_of(make_plane(4, 4), std::make_shared<BtfSurface>(lambertian(rho))));
    point.add_light(std::make_shared<PointLight>(Vec3{0, 2, 0}, Rgb{8, 8, 8}));
    point.commit();
    const RenderResult p = render(point, options);
    EXPECT_NEAR(p.color.at(4, 4, 1), rho / kPi * 8 / 4, 2e-4);
}

// A sphere light of radiance Le and radius r whose centre is d above a Lambertian plane gives
// irradiance π·Le·(r/d)² below it, so L = ρ·Le·(r/d)². The plane is wide, so the scene's ray
// offset (relative to the extent) is large next to the light's closeness: the shadow ray towards
// the light must not count the light itself as a blocker (it did: 36 % of the value with this
// 40-wide plane, 98.5 % with a 4-wide one).
TEST(Render, SphereLightCloseAboveAWidePlane) {
    const float rho = 0.6f;
    const double r = 0.35, d = 1, Le = 4;
    Scene scene;
    scene.camera = looking_down(9);
    scene.camera.position = {0, 3, 2};  // beside the light, not through it
    scene.camera.fov = 1;               // the centre pixel sees the point under the light
    scene.add_object(object_of(make_plane(40, 40), std::make_shared<BtfSurface>(lambertian(rho))));
    scene.add_light(std::make_shared<SphereLight>(Vec3{0, d, 0}, r, Rgb{4, 4, 4}));
    scene.commit();
    RenderOptions options;
    options.spp = 256;
    options.integrator.max_depth = 1;
    const RenderResult result = render(scene, options);
    // Monte Carlo over the light's cone (fixed seed): a few per cent at most.
    EXPECT_NEAR(result.color.at(4, 4, 0), rho * Le * (r / d) * (r / d), 0.02 * rho * Le * r * r);
}

TEST(Render, WhiteFurnaceConverges) {
    // A ρ = 1 diffuse sphere in a uniform environment of radiance 1 reflects exactly 1; so does a
    // ρ = 1 Lambertian BTF through its generic tabulated sampler, filtered deterministically
    // (blended view tables) and stochastically (the selected texel's and view's table alone).
    Image white(32, 16, 3, 1.0f);
    for (int variant = 0; variant < 3; ++variant) {
        Scene scene;
        scene.camera.position = {0, 0, 4};
        scene.camera.look_at = {0, 0, 0};
        scene.camera.fov = 20;
        scene.camera.width = scene.camera.height = 16;
        std::shared_ptr<const Surface> surface;
        if (variant == 0)
            surface = std::make_shared<DiffuseSurface>(Rgb{1, 1, 1});
        else
            surface = std::make_shared<BtfSurface>(lambertian(1));
        scene.add_object(object_of(make_sphere(1, 64), surface));
        scene.add_light(
            std::make_shared<EnvironmentLight>(std::make_shared<const EnvironmentMap>(white)));
        scene.commit();
        RenderOptions options;
        options.spp = 64;
        options.integrator.filter = variant == 2 ? Filter::kStochastic : Filter::kDeterministic;
        const RenderResult r = render(scene, options);
        EXPECT_NEAR(mean_channel(r.color, 0), 1.0, 0.01) << "variant " << variant;
        EXPECT_NEAR(mean_channel(r.color, 2), 1.0, 0.01) << "variant " << variant;
    }
}

TEST(Render, MisLightOnlyAndMaterialOnlyAgree) {
    // A glossy metal plane and a diffuse sphere lit by a sphere light and a sky: the three ways of
    // counting direct light are unbiased estimators of the same image.
    Scene scene;
    scene.camera.position = {0, 2, 4};
    scene.camera.look_at = {0, 0, 0};
    scene.camera.fov = 40;
    scene.camera.width = scene.camera.height = 24;
    scene.add_object(object_of(make_plane(6, 6),
                               std::make_shared<ConductorSurface>(Rgb{0.9f, 0.7f, 0.5f}, 0.3)));
    TriangleMesh ball = make_sphere(0.7, 48);
    transform(ball, Transform::translate({0, 0.7, 0}));
    scene.add_object(
        object_of(std::move(ball), std::make_shared<DiffuseSurface>(Rgb{0.7f, 0.5f, 0.3f})));
    scene.add_light(std::make_shared<SphereLight>(Vec3{1.5, 2.5, 1}, 0.5, Rgb{6, 6, 6}));
    scene.add_light(std::make_shared<EnvironmentLight>(std::make_shared<const EnvironmentMap>(
        EnvironmentMap::make_sky(64, 32, {0.3, 0.8, 0.2}), 1.0)));
    scene.commit();
    double means[3][3];
    for (int s = 0; s < 3; ++s) {
        RenderOptions options;
        options.spp = 128;
        options.integrator.max_depth = 3;
        options.integrator.strategy = LightStrategy(s);
        const RenderResult r = render(scene, options);
        for (int c = 0; c < 3; ++c) means[s][c] = mean_channel(r.color, c);
    }
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(means[1][c] / means[0][c], 1.0, 0.03) << "light only, channel " << c;
        EXPECT_NEAR(means[2][c] / means[0][c], 1.0, 0.05) << "material only, channel " << c;
    }
}

// A BTF that reflects light arriving from the +x side of its local frame (the +u side) brightly
// and from the −x side dimly.
std::shared_ptr<const Material> azimuth_material() {
    const DirectionSet& ubo = DirectionSet::ubo81();
    return std::make_shared<test::FunctionMaterial>(
        8, 8, Sampling{ubo, ubo}, [](const Uv&, const Vec3& wi, const Vec3&) {
            const float side = wi.x > 0 ? 1.0f : 0.1f;
            return Rgb{side, side, side} * float(std::max(wi.z, 0.0));
        });
}

// The world direction in which the mapped u grows at the hit of the ray through pixel (x, y),
// from the hits of two neighbouring rays: what the frame's tangent must be.
Vec3 finite_difference_du(const Scene& scene, double x, double y) {
    const Hit h0 = scene.intersect(scene.camera.ray(x, y));
    const Hit hx = scene.intersect(scene.camera.ray(x + 0.05, y));
    const Hit hy = scene.intersect(scene.camera.ray(x, y + 0.05));
    const Vec3 a = hx.position - h0.position, b = hy.position - h0.position;
    const double au = hx.uv.u - h0.uv.u, av = hx.uv.v - h0.uv.v;
    const double bu = hy.uv.u - h0.uv.u, bv = hy.uv.v - h0.uv.v;
    // dP/du from a = P_u au + P_v av, b = P_u bu + P_v bv.
    const double det = au * bv - av * bu;
    return normalize((a * bv - b * av) / det);
}

TEST(Render, TangentFrameFollowsIncreasingU) {
    struct Case {
        const char* name;
        TriangleMesh mesh;
        double uv_rotation;
        bool from_below = false;  // the camera sees the surface's back
    };
    std::vector<Case> cases;
    cases.push_back({"plane", make_plane(4, 4), 0});
    cases.push_back({"plane, uv rotated 90°", make_plane(4, 4), 90});
    cases.push_back({"plane from below, uv rotated 90°", make_plane(4, 4), 90, true});
    cases.push_back({"plane from below, uv rotated 30°", make_plane(4, 4), 30, true});
    cases.push_back({"sphere", make_sphere(1, 96), 0});
    cases.push_back({"cylinder", make_cylinder(1, 2, 96), 0});
    cases.push_back({"cylinder, uv rotated 30°", make_cylinder(1, 2, 96), 30});
    for (Case& c : cases) {
        for (double side : {1.0, -1.0}) {
            Scene scene;
            scene.camera.position = {0.3, c.from_below ? -2.5 : 2.5, 3};
            scene.camera.look_at = {0, c.from_below ? -0.2 : 0.2, 0};
            scene.camera.fov = 10;
            scene.camera.width = scene.camera.height = 9;
            SceneObject o = object_of(c.mesh, std::make_shared<BtfSurface>(azimuth_material()));
            o.uv.rotation = c.uv_rotation;
            o.uv.scale_u = o.uv.scale_v = 2;
            scene.add_object(std::move(o));
            scene.commit();
            const Vec3 du = finite_difference_du(scene, 4.5, 4.5);
            const Hit hit = scene.intersect(scene.camera.ray(4.5, 4.5));
            ASSERT_TRUE(hit.found()) << c.name;
            EXPECT_GT(dot(hit.tangent, du), 0.98) << c.name;
            // Light from the +u (side 1) or −u (side −1) half, 40° above the surface.
            const Vec3 towards = normalize(hit.normal * std::cos(radians(50)) +
                                           normalize(du - hit.normal * dot(du, hit.normal)) *
                                               (side * std::sin(radians(50))));
            scene.add_light(std::make_shared<DirectionalLight>(towards, Rgb{1, 1, 1}));
            RenderOptions options;
            options.spp = 1;
            options.integrator.max_depth = 1;
            const double expected = (side > 0 ? 1.0 : 0.1) * std::cos(radians(50)) / kPi;
            Scene lit = std::move(scene);
            lit.commit();
            const RenderResult r = render(lit, options);
            EXPECT_NEAR(r.color.at(4, 4, 1), expected, 0.02 * expected)
                << c.name << " side " << side;
        }
    }
}

TEST(Render, SurfaceSamplingDensities) {
    const DiffuseSurface diffuse({0.5f, 0.5f, 0.5f});
    const ConductorSurface metal({0.9f, 0.9f, 0.9f}, 0.25);
    const BtfSurface btf(lambertian(0.8f));  // the generic tabulated sampler
    const Vec3 wo = normalize(Vec3{0.4, -0.2, 0.8});
    for (const Filter filter : {Filter::kDeterministic, Filter::kStochastic})
        for (const Surface* s :
             {static_cast<const Surface*>(&diffuse), static_cast<const Surface*>(&metal),
              static_cast<const Surface*>(&btf)}) {
            const Vertex v = s->vertex({0.3, 0.6}, wo, filter, 0.37);
            // pdf() integrates to at most 1 over the hemisphere (the conductor loses the half
            // vectors that reflect below the horizon), and sample() reports pdf() of what it draws.
            double integral = 0;
            constexpr int kN = 256;
            for (int i = 0; i < kN; ++i)
                for (int j = 0; j < kN; ++j) {
                    const double cos_t = (i + 0.5) / kN, phi = 2 * kPi * (j + 0.5) / kN;
                    const double sin_t = std::sqrt(1 - cos_t * cos_t);
                    integral += s->pdf(v, {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t});
                }
            integral *= 2 * kPi / (double(kN) * kN);
            EXPECT_LE(integral, 1.01);
            EXPECT_GT(integral, 0.9);
            if (s != &metal) EXPECT_NEAR(integral, 1.0, 0.01);  // nothing drawn below the horizon
            double weight_mean = 0, value_integral = 0;
            for (int i = 0; i < 64; ++i)
                for (int j = 0; j < 64; ++j) {
                    const LightSample ls = s->sample(v, (i + 0.5) / 64, (j + 0.5) / 64);
                    if (ls.pdf > 0) {
                        EXPECT_NEAR(ls.pdf, s->pdf(v, ls.wi), 1e-9 * (1 + ls.pdf));
                    }
                    weight_mean += ls.weight.g;
                }
            weight_mean /= 64 * 64;
            for (int i = 0; i < kN; ++i)
                for (int j = 0; j < kN; ++j) {
                    const double cos_t = (i + 0.5) / kN, phi = 2 * kPi * (j + 0.5) / kN;
                    const double sin_t = std::sqrt(1 - cos_t * cos_t);
                    value_integral +=
                        s->eval(v, {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t}).g;
                }
            value_integral *= 2 * kPi / (double(kN) * kN);
            // E[value / pdf] = ∫ value dω where pdf > 0.
            EXPECT_NEAR(weight_mean, value_integral, 0.02 * value_integral);
        }
}

// A BTF whose terms have both signs, as a truncated factorization's do: a Lambertian lobe times
// `even` on the texels with x + y even and times `odd` on the others.
class SignedTermsMaterial final : public Material {
  public:
    SignedTermsMaterial(float even, float odd) : m_even(even), m_odd(odd) {}
    int width() const override { return 8; }
    int height() const override { return 8; }
    const Sampling& sampling() const override { return m_sampling; }
    Rgb eval_sample(int x, int y, int, int light) const override {
        const float sign = (x + y) % 2 == 0 ? m_even : m_odd;
        return Rgb{1, 1, 1} * (sign * float(std::max(m_sampling.lights.vector(light).z, 0.0)));
    }
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override {
        return lookup6d(uv, width(), height(), view_interpolator().weights(wo),
                        light_interpolator().weights(wi), [&](int x, int y, int view, int light) {
                            return eval_sample(x, y, view, light);
                        });
    }

  private:
    float m_even, m_odd;
    Sampling m_sampling{DirectionSet::ubo81(), DirectionSet::ubo81()};
};

// A surface's values are signed with either filter, so the terms of a stochastic vertex average
// to the deterministic value: clamping each term at zero would give the lobe times 1.5 here
// instead of 1.
TEST(Render, StochasticTermsKeepTheirSignAndAverageToTheFilteredValue) {
    const BtfSurface surface(std::make_shared<SignedTermsMaterial>(3.0f, -1.0f));
    const Vec3 wo = normalize(Vec3{0.1, 0.2, 0.9}), wi = normalize(Vec3{-0.3, 0.4, 0.7});
    // Half-way between texel centres in both axes (the lobe times 1), and the centre of a texel
    // with x + y odd (times −1).
    for (const Uv& uv : {Uv{0.25, 0.5}, Uv{1.5 / 8, 0.5 / 8}}) {
        const float expected =
            surface.eval(surface.vertex(uv, wo, Filter::kDeterministic, 0), wi).g;
        ASSERT_GT(std::abs(expected), 0.1f);
        constexpr int kN = 4096;
        double mean = 0;
        int negative = 0;
        for (int i = 0; i < kN; ++i) {
            const Vertex v = surface.vertex(uv, wo, Filter::kStochastic, (i + 0.5) / kN);
            const float term = surface.eval(v, wi).g;
            negative += term < 0;
            mean += term / kN;
        }
        EXPECT_GT(negative, expected > 0 ? kN / 4 : kN - 1);
        EXPECT_NEAR(mean, expected, 0.01 * std::abs(expected)) << "uv " << uv.u << ", " << uv.v;
    }
}

// What render() clamps is the pixel: a plane whose BTF is negative everywhere renders black with
// either filter, and the positive plane beside it does not.
TEST(Render, PixelsAreClampedAtZeroNotTerms) {
    for (const Filter filter : {Filter::kDeterministic, Filter::kStochastic}) {
        Scene scene;
        scene.camera = looking_down(8);
        TriangleMesh left = make_plane(2, 4), right = make_plane(2, 4);
        transform(left, Transform::translate({-1, 0, 0}));
        transform(right, Transform::translate({1, 0, 0}));
        scene.add_object(object_of(
            left, std::make_shared<BtfSurface>(std::make_shared<SignedTermsMaterial>(-1, -1))));
        scene.add_object(object_of(
            right, std::make_shared<BtfSurface>(std::make_shared<SignedTermsMaterial>(3, -1))));
        scene.add_light(
            std::make_shared<DirectionalLight>(normalize(Vec3{0.3, 1, 0.2}), Rgb{2, 2, 2}));
        scene.commit();
        RenderOptions options;
        options.spp = 4;
        options.integrator.filter = filter;
        const Image image = render(scene, options).color;
        // The planes meet at the centre of the view: four columns of pixels see each.
        double half[2] = {0, 0};
        for (int y = 0; y < 8; ++y)
            for (int x = 0; x < 8; ++x) {
                ASSERT_GE(image.at(x, y, 1), 0.0f) << "pixel " << x << ", " << y;
                half[x / 4] += image.at(x, y, 1);
            }
        EXPECT_EQ(std::min(half[0], half[1]), 0.0) << to_string(filter);
        EXPECT_GT(std::max(half[0], half[1]), 0.0) << to_string(filter);
    }
}

// The first surface's filter numbers of a pixel walk two Kronecker sequences: uniform starts that
// differ between pixels, every prefix of passes stratified in each number, and the pairs spread
// over the square.
TEST(Render, PrimaryFilterNumbersAreStratified) {
    std::vector<double> starts;
    for (uint64_t pixel = 0; pixel < 64; ++pixel) {
        starts.push_back(primary_filter_numbers(7, pixel, 0).u);
        for (const int n : {8, 64, 500}) {
            std::vector<double> u, light;
            int quadrant[2][2] = {{0, 0}, {0, 0}};
            for (int pass = 0; pass < n; ++pass) {
                const FilterNumbers f = primary_filter_numbers(7, pixel, uint64_t(pass));
                for (const double x : {f.u, f.light}) {
                    ASSERT_GE(x, 0.0);
                    ASSERT_LT(x, 1.0);
                }
                u.push_back(f.u), light.push_back(f.light);
                ++quadrant[f.u >= 0.5][f.light >= 0.5];
            }
            for (auto [x, bound] : {std::pair{u, 1.9}, std::pair{light, 2.1}}) {
                std::sort(x.begin(), x.end());
                double gap = x.front() + 1 - x.back();
                for (size_t i = 1; i < x.size(); ++i) gap = std::max(gap, x[i] - x[i - 1]);
                EXPECT_LT(gap, bound / n) << "pixel " << pixel << ", " << n << " passes";
            }
            if (n >= 64)
                for (const auto& row : quadrant)
                    for (const int count : row) EXPECT_NEAR(count, n / 4.0, 0.05 * n);
        }
    }
    std::sort(starts.begin(), starts.end());
    EXPECT_EQ(std::unique(starts.begin(), starts.end()), starts.end());
    EXPECT_LT(starts.front(), 0.1);
    EXPECT_GT(starts.back(), 0.9);
    EXPECT_NE(primary_filter_numbers(8, 0, 0).u, primary_filter_numbers(7, 0, 0).u);
}

// Where the stratified numbers pay: one camera ray (no jitter) onto a BTF whose neighbouring
// texels differ in sign, under a directional light, so that a pixel's samples differ only in what
// the stochastic filter selects. 256 samples through the stratified numbers land far closer to
// the filtered value than 256 with numbers from the sample streams.
TEST(Render, StratifiedPrimaryFilterNumbersConvergeFaster) {
    Scene scene;
    scene.camera = looking_down(8);
    scene.add_object(
        object_of(make_plane(4, 4),
                  std::make_shared<BtfSurface>(std::make_shared<SignedTermsMaterial>(3, -1))));
    scene.add_light(std::make_shared<DirectionalLight>(normalize(Vec3{0.3, 1, 0.2}), Rgb{2, 2, 2}));
    scene.commit();
    IntegratorOptions stochastic, deterministic;
    stochastic.max_depth = deterministic.max_depth = 1;
    deterministic.filter = Filter::kDeterministic;
    constexpr int kSamples = 256;
    double error_stratified = 0, error_independent = 0;
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            const uint64_t pixel = uint64_t(y) * 8 + x;
            const Ray ray = scene.camera.ray(x + 0.37, y + 0.61);
            Rng first(1, pixel, 0);
            const double reference = radiance(scene, ray, first, deterministic).g;
            double stratified = 0, independent = 0;
            for (int pass = 0; pass < kSamples; ++pass) {
                Rng a(1, pixel, uint64_t(pass)), b(1, pixel, uint64_t(pass));
                stratified += radiance(scene, ray, a, stochastic, nullptr,
                                       primary_filter_numbers(1, pixel, uint64_t(pass)))
                                  .g;
                independent += radiance(scene, ray, b, stochastic).g;
            }
            error_stratified += std::abs(stratified / kSamples - reference);
            error_independent += std::abs(independent / kSamples - reference);
        }
    EXPECT_GT(error_independent, 0.0);
    EXPECT_LT(error_stratified, 0.2 * error_independent)
        << "stratified " << error_stratified / 64 << ", independent " << error_independent / 64;
}

TEST(Render, SameImageForAnyThreadCount) {
    Scene scene;
    scene.camera.width = scene.camera.height = 20;
    scene.add_object(
        object_of(make_sphere(1, 32), std::make_shared<DiffuseSurface>(Rgb{0.5f, 0.6f, 0.7f})));
    scene.add_light(std::make_shared<SphereLight>(Vec3{2, 2, 2}, 0.5, Rgb{5, 5, 5}));
    scene.commit();
    RenderOptions options;
    options.spp = 3;
    RenderResult one, two;
    {
        ThreadLimit limit(1);
        one = render(scene, options);
    }
    {
        ThreadLimit limit(2);
        two = render(scene, options);
    }
    EXPECT_EQ(one.color.values(), two.color.values());
    options.seed = 2;
    EXPECT_NE(render(scene, options).color.values(), one.color.values());
}

class SceneFile : public ::testing::Test {
  protected:
    void SetUp() override {
        m_dir = std::filesystem::temp_directory_path() /
                ("btf_scene_test_" + std::to_string(::getpid()));
        std::filesystem::create_directories(m_dir);
    }
    void TearDown() override { std::filesystem::remove_all(m_dir); }
    std::string error_of(const std::string& json) {
        try {
            parse_scene(json, "s.json", m_dir);
        } catch (const Error& e) {
            return e.what();
        }
        return "no error";
    }
    std::filesystem::path m_dir;
};

TEST_F(SceneFile, ReadsEveryShapeAndLight) {
    const std::string obj = (m_dir / "quad.obj").string();
    std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                          "f 1/1 2/2 3/3 4/4\n";
    const LoadedScene s = parse_scene(R"({
      "camera": {"position": [0, 2, 5], "look_at": [0, 0, 0], "fov": 30, "width": 40, "height": 30},
      "render": {"integrator": "path", "spp": 4, "max_depth": 5, "seed": 9, "exposure": 1},
      "objects": [
        {"shape": "plane", "width": 4, "depth": 4, "material": {"type": "diffuse", "albedo": 0.4}},
        {"shape": "sphere", "radius": 0.5, "position": [0, 0.5, 0], "uv_scale": [2, 3],
         "material": {"type": "conductor", "f0": [0.9, 0.6, 0.5], "roughness": 0.3}},
        {"shape": "cylinder", "radius": 0.3, "height": 1, "rotation": [0, 45, 0], "scale": 0.5,
         "material": {"type": "diffuse"}},
        {"shape": "torus", "major_radius": 0.5, "minor_radius": 0.1, "uv_rotation": 30,
         "material": {"type": "diffuse"}},
        {"shape": "obj", "file": "quad.obj", "material": {"type": "diffuse"}}
      ],
      "lights": [
        {"type": "point", "position": [0, 3, 0], "intensity": 5},
        {"type": "directional", "direction": [1, 1, 0], "irradiance": [1, 1, 1]},
        {"type": "sphere", "center": [2, 2, 2], "radius": 0.3, "radiance": 4},
        {"type": "environment", "sky": {"sun_elevation": 40, "width": 64}, "scale": 0.5}
      ]})",
                                      "s.json", m_dir);
    EXPECT_EQ(s.scene.objects().size(), 5u);
    EXPECT_EQ(s.scene.lights().size(), 4u);
    EXPECT_NE(s.scene.environment(), nullptr);
    EXPECT_EQ(s.scene.camera.width, 40);
    EXPECT_EQ(s.settings.options.spp, 4);
    EXPECT_EQ(s.settings.options.integrator.max_depth, 5);
    EXPECT_EQ(s.settings.options.seed, 9u);
    EXPECT_DOUBLE_EQ(s.scene.objects()[1].uv.scale_v, 3);
}

TEST_F(SceneFile, ErrorsNameTheFileAndThePlace) {
    const std::string camera = R"("camera": {"position": [0, 2, 5]})";
    EXPECT_EQ(error_of("{" + camera + R"(, "objects": [], "lihgts": []})"),
              "s.json: unknown key \"lihgts\"");
    EXPECT_EQ(
        error_of(
            "{" + camera +
            R"(, "objects": [{"shape": "sphere", "radious": 1, "material": {"type": "diffuse"}}]})"),
        "s.json: objects[0]: unknown key \"radious\" for a sphere");
    EXPECT_EQ(
        error_of(
            "{" + camera +
            R"(, "objects": [{"shape": "sphere", "material": {"type": "diffuse", "albedo": "red"}}]})"),
        "s.json: objects[0].material: \"albedo\" must be an array of 3 numbers");
    EXPECT_EQ(error_of("{" + camera +
                       R"(, "objects": [{"shape": "cube", "material": {"type": "diffuse"}}]})"),
              "s.json: objects[0]: unknown shape \"cube\" (plane, sphere, cylinder, torus, obj)");
    const std::string missing = error_of(
        "{" + camera +
        R"(, "objects": [{"shape": "plane", "material": {"type": "btf", "file": "nope.btfpkg"}}]})");
    EXPECT_NE(missing.find("s.json: objects[0].material: "), std::string::npos) << missing;
    EXPECT_NE(missing.find("nope.btfpkg: no such file"), std::string::npos) << missing;
    EXPECT_EQ(error_of("{" + camera + R"(, "objects": [], "lights": [{"type": "laser"}]})"),
              "s.json: lights[0]: unknown light type \"laser\" (point, directional, sphere, "
              "environment)");
    EXPECT_EQ(error_of("{\"camera\": {\"fov\": 200}, \"objects\": []}"),
              "s.json: camera: \"fov\" = 200 is outside [1, 179]");
    EXPECT_NE(error_of("{ not json").find("s.json: not valid JSON"), std::string::npos);
}

}  // namespace
}  // namespace btf::render
