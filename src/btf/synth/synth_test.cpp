// SPDX-License-Identifier: MIT
#include "btf/synth/synth.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "btf/core/color.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::synth {
namespace {

using ::testing::HasSubstr;

const Sampling& ubo() {
    static const Sampling sampling{DirectionSet::ubo81(), DirectionSet::ubo81()};
    return sampling;
}

int ubo_index(double theta_deg, double phi_deg) {
    const int i = DirectionSet::ubo81().find(Direction::from_degrees(theta_deg, phi_deg));
    EXPECT_GE(i, 0) << theta_deg << " " << phi_deg;
    return i;
}

double mean_luminance(const Image& image) {
    double sum = 0;
    for (int y = 0; y < image.height(); ++y)
        for (int x = 0; x < image.width(); ++x) sum += luminance(image.rgb(x, y));
    return sum / double(image.num_pixels());
}

TEST(Synth, PresetsHaveNamesAndDescriptions) {
    const auto names = preset_names();
    EXPECT_GE(names.size(), 5u);
    EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
    for (const PresetInfo& p : presets()) {
        EXPECT_FALSE(p.name.empty());
        EXPECT_GT(p.description.size(), 20u) << p.name;
        EXPECT_EQ(p.description.find('\n'), std::string::npos) << p.name;
    }
}

TEST(Synth, UnknownPresetListsTheValidNames) {
    try {
        make("velvet", 16, ubo(), 1);
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(e.what(), HasSubstr("unknown preset 'velvet'"));
        for (const std::string& name : preset_names()) EXPECT_THAT(e.what(), HasSubstr(name));
    }
}

TEST(Synth, SizeAndIndexLimitsAreChecked) {
    for (int size : {0, 3, kMaxSize + 1}) {
        try {
            make("leather", size, ubo(), 1);
            FAIL() << "expected an error for size " << size;
        } catch (const Error& e) {
            EXPECT_THAT(e.what(), HasSubstr(fmt::format("size {} is outside [4, 2048]", size)));
        }
    }
    const auto source = make("leather", 8, ubo(), 1);
    Image out;
    try {
        source->read_image(81, 0, out);
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(e.what(), HasSubstr("(view 81, light 0) is outside the sampling (81 views"));
    }
    EXPECT_THROW(source->read_image(0, -1, out), Error);
    EXPECT_THROW(make("leather", 8, Sampling{}, 1), Error);
}

TEST(Synth, DescribesItself) {
    const auto source = make("ceramic_tiles", 16, ubo(), 5);
    EXPECT_EQ(source->width(), 16);
    EXPECT_EQ(source->height(), 16);
    EXPECT_EQ(source->num_views(), 81);
    EXPECT_EQ(source->num_lights(), 81);
    EXPECT_EQ(source->info().format, "synthetic");
    EXPECT_THAT(source->info().note, HasSubstr("ceramic_tiles"));
    const Sampling dome{DirectionSet::dome151(), DirectionSet::ubo81()};
    const auto other = make("leather", 8, dome, 5);
    EXPECT_EQ(other->num_views(), 151);
    EXPECT_EQ(other->image(150, 80).width(), 8);
}

TEST(Synth, DeterministicPerSeed) {
    const std::vector<std::pair<int, int>> images = {{0, 0}, {30, 7}, {80, 45}};
    for (const std::string& preset : preset_names()) {
        const auto a = make(preset, 24, ubo(), 7);
        const auto b = make(preset, 24, ubo(), 7);
        const auto c = make(preset, 24, ubo(), 8);
        for (auto [view, light] : images) {
            const Image ia = a->image(view, light);
            EXPECT_EQ(ia.values(), b->image(view, light).values()) << preset;
            EXPECT_NE(ia.values(), c->image(view, light).values()) << preset;
        }
    }
}

TEST(Synth, IndependentOfThreadCount) {
    const std::vector<std::pair<int, int>> images = {{0, 3}, {19, 0}, {44, 60}, {80, 80}};
    for (std::string preset : {"ceramic_tiles", "lacquered_wood", "woven_fabric"}) {
        std::vector<Image> single;
        {
            ThreadLimit limit(1);
            const auto source = make(preset, 32, ubo(), 3);
            for (auto [view, light] : images) single.push_back(source->image(view, light));
        }
        const auto source = make(preset, 32, ubo(), 3);
        // Read them concurrently, in another order, so the caches fill differently too.
        std::vector<Image> parallel(images.size());
        parallel_for(0, int64_t(images.size()), [&](int64_t i) {
            const size_t j = images.size() - 1 - size_t(i);
            parallel[j] = source->image(images[j].first, images[j].second);
        });
        for (size_t i = 0; i < images.size(); ++i)
            EXPECT_EQ(single[i].values(), parallel[i].values()) << preset << " image " << i;
    }
}

TEST(Synth, SmallCacheGivesTheSameImages) {
    SynthOptions tiny;
    tiny.cache_bytes = 1;  // every entry is evicted as soon as another one is computed
    const auto cached = make("knitted_wool", 16, ubo(), 2);
    const auto evicting = make("knitted_wool", 16, ubo(), 2, tiny);
    for (int i = 0; i < 40; ++i) {
        const int view = (i * 37) % 81, light = (i * 53) % 81;
        EXPECT_EQ(cached->image(view, light).values(), evicting->image(view, light).values());
    }
}

// Mean absolute difference across the wrap-around seam versus between interior neighbours.
template <typename Get>
void expect_tileable(Get&& get, int n, const std::string& what) {
    double seam_x = 0, seam_y = 0, inner_x = 0, inner_y = 0;
    for (int i = 0; i < n; ++i) {
        seam_x += std::abs(get(n - 1, i) - get(0, i));
        seam_y += std::abs(get(i, n - 1) - get(i, 0));
        for (int k = 0; k + 1 < n; ++k) {
            inner_x += std::abs(get(k + 1, i) - get(k, i));
            inner_y += std::abs(get(i, k + 1) - get(i, k));
        }
    }
    seam_x /= n, seam_y /= n, inner_x /= n * (n - 1), inner_y /= n * (n - 1);
    EXPECT_LE(seam_x, 2.0 * inner_x + 1e-6) << what;
    EXPECT_LE(seam_y, 2.0 * inner_y + 1e-6) << what;
}

TEST(Synth, TileableInUAndV) {
    for (const std::string& preset : preset_names()) {
        const auto source = make(preset, 64, ubo(), 4);
        const Surface& s = static_cast<const SynthSource&>(*source).surface();
        expect_tileable([&](int x, int y) { return double(s.height(x, y)); }, 64,
                        preset + " height");
        expect_tileable([&](int x, int y) { return double(luminance(s.albedo[y * 64 + x])); }, 64,
                        preset + " albedo");
        const Image oblique = source->image(ubo_index(60, 72), ubo_index(75, 195));
        expect_tileable([&](int x, int y) { return double(luminance(oblique.rgb(x, y))); }, 64,
                        preset + " image");
    }
}

TEST(Synth, PresetsArePeriodic) {
    for (const std::string& preset : preset_names())
        for (int i = 0; i < 200; ++i) {
            const double u = hash_unit(1, i, 1), v = hash_unit(1, i, 2);
            const PresetSample a = sample_preset(preset, 5, u, v);
            for (auto [du, dv] : {std::pair{1.0, 0.0}, {0.0, 1.0}, {-1.0, 2.0}}) {
                const PresetSample b = sample_preset(preset, 5, u + du, v + dv);
                EXPECT_NEAR(a.height, b.height, 1e-9) << preset << " at " << u << ", " << v;
                EXPECT_NEAR(a.albedo.r, b.albedo.r, 1e-5) << preset << " at " << u << ", " << v;
                EXPECT_NEAR(a.albedo.b, b.albedo.b, 1e-5) << preset << " at " << u << ", " << v;
            }
        }
    // The surface is the preset sampled at the texel centres.
    const Surface s = make_surface("leather", 16, 5);
    const PresetSample p = sample_preset("leather", 5, 3.5 / 16, 7.5 / 16);
    EXPECT_NEAR(s.height(3, 7), p.height * 16, 1e-5);
    EXPECT_NEAR(s.albedo[7 * 16 + 3].g, p.albedo.g, 1e-6);
}

TEST(Synth, ValuesAreFiniteNonNegativeAndBounded) {
    for (const std::string& preset : preset_names()) {
        const auto source = make(preset, 16, ubo(), 9);
        double max_value = 0;
        for (int view : {0, 19, 45, 80})
            for (int light = 0; light < 81; ++light) {
                const Image image = source->image(view, light);
                for (float v : image.values()) {
                    ASSERT_TRUE(std::isfinite(v)) << preset;
                    ASSERT_GE(v, 0.0f) << preset;
                    max_value = std::max(max_value, double(v));
                }
            }
        // Narrow highlights exceed 1; the largest, a clear coat seen in the mirror direction at
        // 75° (π·D·G·F / (4 cos θo) with D = 1/(π α²)), stays below 100.
        EXPECT_LT(max_value, 100.0) << preset;
        EXPECT_GT(max_value, 0.05) << preset;
    }
}

TEST(Synth, EnergyIsPlausible) {
    for (const std::string& preset : preset_names()) {
        const auto source = make(preset, 32, ubo(), 1);
        // Directional albedo for the zenith view by reciprocity: (1/π)∫ value dω over the
        // lights, each of the 81 lights standing for about 2π/81 sr.
        double albedo = 0;
        for (int light = 0; light < 81; ++light)
            albedo += mean_luminance(source->image(0, light)) * 2.0 / 81.0;
        EXPECT_GT(albedo, 0.02) << preset;
        EXPECT_LT(albedo, 1.1) << preset;
        // A light at 45° on a mostly diffuse material: about albedo · cos 45°.
        const double at45 = mean_luminance(source->image(0, ubo_index(45, 20)));
        EXPECT_LT(at45, 0.9) << preset;
    }
    // The zenith image of a diffuse material is its albedo-like value.
    for (std::string preset : {"woven_fabric", "knitted_wool", "leather"}) {
        const double zenith = mean_luminance(make(preset, 32, ubo(), 1)->image(0, 0));
        EXPECT_GT(zenith, 0.05) << preset;
        EXPECT_LT(zenith, 0.9) << preset;
    }
}

// Texels of the tiles' vertical grout joints (x near a multiple of size/4), away from the
// crossings with horizontal joints, and low in the height field.
std::vector<int> vertical_groove_floor(const Surface& s) {
    const int n = s.size, tile = n / 4;
    const float lo = s.height.min(), hi = s.height.max();
    std::vector<int> texels;
    for (int y = 0; y < n; ++y) {
        const int dy = std::min(y % tile, tile - 1 - y % tile);
        if (dy < 4) continue;
        for (int x = 0; x < n; ++x) {
            const int dx = std::min(x % tile, tile - 1 - x % tile);
            if (dx == 0 && s.height(x, y) < lo + 0.25f * (hi - lo)) texels.push_back(y * n + x);
        }
    }
    return texels;
}

TEST(Synth, TilesCastShadowsIntoTheirGrooves) {
    const auto source = make("ceramic_tiles", 64, ubo(), 1);
    const Surface& s = static_cast<const SynthSource&>(*source).surface();
    const std::vector<int> floor = vertical_groove_floor(s);
    ASSERT_GT(floor.size(), 50u);
    auto mean_over = [&](const Image& image) {
        double sum = 0;
        for (int i : floor) sum += luminance(image.rgb(i % 64, i / 64));
        return sum / double(floor.size());
    };
    const double zenith = mean_over(source->image(0, 0));
    // Grazing light across the groove (from +x): its walls hide the floor.
    const double across = mean_over(source->image(0, ubo_index(75, 0)));
    // The same elevation along the groove (from +y): the floor stays lit.
    const double along = mean_over(source->image(0, ubo_index(75, 90)));
    const double cos75 = std::cos(radians(75));
    EXPECT_GT(along, 0.6 * cos75 * zenith);
    EXPECT_LT(across, 0.3 * cos75 * zenith);
    EXPECT_LT(across, 0.3 * along);
    // Shadowed texels are not black: light bounced off the lit tiles reaches them.
    EXPECT_GT(across, 0.0);
}

TEST(Synth, ObliqueViewsShowParallax) {
    // View θ = 60°, φ = 0 sees a point at height h (texel units) above the reference plane
    // through the output texel shifted by (h − reference)·tan θ away from the viewer's azimuth.
    const int n = 128;
    const auto source = make("ceramic_tiles", n, ubo(), 1);
    const Surface& s = static_cast<const SynthSource&>(*source).surface();
    // A light far from the mirror direction of both views, so both images show the
    // (view-independent) diffuse shading of the glaze.
    const int light = ubo_index(45, 100);
    const Image top = source->image(0, light);
    const Image side = source->image(ubo_index(60, 0), light);
    const double tan60 = std::tan(radians(60));
    const float hi = s.height.max(), lo = s.height.min();
    double err_parallax = 0, err_none = 0, err_reverse = 0, shift_sum = 0;
    int count = 0;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            // Solve q = p + (H(q) − reference)·tan θ by fixed-point iteration (tile tops are
            // nearly flat, so it converges; texels that see grooves are skipped).
            const double px = x + 0.5, py = y + 0.5;
            double qx = px;
            for (int k = 0; k < 20; ++k)
                qx = px + (s.height.bilinear(qx, py) - s.reference) * tan60;
            // Keep rays that travel over tile tops only (no groove between p and q).
            bool on_top = true;
            for (double sx = std::min(px, qx) - 3; sx <= std::max(px, qx) + 3; sx += 0.5)
                on_top = on_top && s.height.bilinear(sx, py) > hi - 0.2f * (hi - lo);
            if (!on_top) continue;
            const double shift = qx - px;
            shift_sum += shift;
            const double seen = luminance(side.rgb(x, y));
            auto at = [&](double sx) {
                return double(luminance(top.bilinear(std::fmod(sx + 10 * n, double(n)), py)));
            };
            err_parallax += std::abs(seen - at(px + shift));
            err_none += std::abs(seen - at(px));
            err_reverse += std::abs(seen - at(px - shift));
            ++count;
        }
    ASSERT_GT(count, n * n / 4);
    EXPECT_GT(shift_sum / count, 1.0);  // tile tops stand above the mean height
    EXPECT_LT(err_parallax, 0.5 * err_none);
    EXPECT_LT(err_parallax, 0.3 * err_reverse);
}

}  // namespace
}  // namespace btf::synth
