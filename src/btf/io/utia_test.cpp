// SPDX-License-Identifier: MIT
#include "btf/io/utia.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>

#include "btf/core/color.h"
#include "btf/io/function_source.h"
#include "btf/io/image_set.h"
#include "btf/testing/support.h"
#include "btf/util/error.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

using btf::test::TempFolder;

using btf::test::error_of;

// A small analytic source: every (view, light, texel) has its own linear RGB value.
FunctionSource test_source(Sampling sampling, int width, int height, float scale = 1.0f) {
    return FunctionSource(
        std::move(sampling), width, height,
        [=](int view, int light, int x, int y) {
            const float t = float(x + 2 * y) / float(width + 2 * height);
            return Rgb{0.05f + 0.9f * float(light % 7) / 6, 0.1f + 0.8f * t,
                       0.02f + 0.9f * float(view % 3) / 2 * (1 - t)} *
                   scale;
        },
        "test");
}

// Lights including angles between whole degrees (23.5°, 52.5°, 7.5°), views at whole degrees;
// both ordered by θ, then φ, as the reader orders them.
Sampling small_sampling() {
    Sampling s;
    s.lights = DirectionSet("lights",
                            {Direction::from_degrees(0, 0), Direction::from_degrees(11, 15),
                             Direction::from_degrees(23.5, 0), Direction::from_degrees(52.5, 7.5),
                             Direction::from_degrees(75, 345)});
    s.views = DirectionSet("views", {Direction::from_degrees(0, 0), Direction::from_degrees(30, 90),
                                     Direction::from_degrees(60, 18)});
    return s;
}

TEST(UtiaNames, WholeAndDecimalDegrees) {
    EXPECT_EQ(
        utia::file_name(Direction::from_degrees(45, 20), Direction::from_degrees(0, 0), "png"),
        "tl045_pl020_tv000_pv000.png");
    EXPECT_EQ(utia::file_name(Direction::from_degrees(23.5, 7.25), Direction::from_degrees(75, 345),
                              "exr"),
              "tl023.5_pl007.25_tv075_pv345.exr");
    // φ carries no information at the zenith and is written as 000.
    EXPECT_EQ(
        utia::file_name(Direction::from_degrees(0, 120), Direction::from_degrees(0, 300), "png"),
        "tl000_pl000_tv000_pv000.png");
    // φ just below 360° is φ = 0.
    EXPECT_EQ(utia::file_name(Direction::from_degrees(15, 359.99999999), Direction{}, "png"),
              "tl015_pl000_tv000_pv000.png");
    EXPECT_THAT(error_of([] { utia::file_name(Direction{}, Direction{}, "tif"); }),
                HasSubstr("unknown UTIA image format 'tif'"));
}

TEST(UtiaRoundTrip, PngWithinEightBits) {
    TempFolder temp;
    const FunctionSource source = test_source(small_sampling(), 6, 4);
    const fs::path folder = temp.path() / "set_png";
    Progress progress;
    utia::write(source, folder, "png", progress);
    EXPECT_EQ(progress.done(), 15u);
    EXPECT_TRUE(fs::exists(folder / "tl023.5_pl000_tv030_pv090.png"));
    EXPECT_TRUE(fs::exists(folder / "tl052.5_pl007.5_tv060_pv018.png"));
    EXPECT_TRUE(utia::probe(folder));

    auto read = utia::open(folder);
    EXPECT_EQ(read->info().format, "UTIA image set");
    EXPECT_FALSE(read->info().hdr);
    ASSERT_EQ(read->width(), 6);
    ASSERT_EQ(read->height(), 4);
    ASSERT_TRUE(read->sampling().lights.same_directions(source.sampling().lights));
    ASSERT_TRUE(read->sampling().views.same_directions(source.sampling().views));
    double worst = 0;
    for (int v = 0; v < 3; ++v)
        for (int l = 0; l < 5; ++l) {
            const Image image = read->image(v, l);
            for (int y = 0; y < 4; ++y)
                for (int x = 0; x < 6; ++x) {
                    const Rgb want = source.value(v, l, x, y), got = image.rgb(x, y);
                    worst = std::max(
                        {worst, double(std::abs(linear_to_srgb(got.r) - linear_to_srgb(want.r))),
                         double(std::abs(linear_to_srgb(got.g) - linear_to_srgb(want.g))),
                         double(std::abs(linear_to_srgb(got.b) - linear_to_srgb(want.b)))});
                }
        }
    EXPECT_LE(worst, 0.5 / 255 + 1e-6);  // one rounding to 8-bit code values

    // Raw encoding keeps the code values.
    OpenOptions raw;
    raw.encoding = Encoding::kRaw;
    const Image raw_image = utia::open(folder, raw)->image(1, 2);
    EXPECT_NEAR(raw_image.rgb(3, 2).g, linear_to_srgb(source.value(1, 2, 3, 2).g),
                0.5 / 255 + 1e-6);
}

TEST(UtiaRoundTrip, ExrWithinHalfPrecisionAndStoredAsXyz) {
    TempFolder temp;
    const FunctionSource source = test_source(small_sampling(), 5, 3, 3.0f);  // HDR values up to 3
    const fs::path folder = temp.path() / "set_exr";
    utia::write(source, folder, "exr");
    auto read = utia::open(folder);
    EXPECT_TRUE(read->info().hdr);
    EXPECT_THAT(read->info().note, HasSubstr("XYZ"));
    ASSERT_TRUE(read->sampling().lights.same_directions(source.sampling().lights));
    for (int v = 0; v < 3; ++v)
        for (int l = 0; l < 5; ++l) {
            const Image image = read->image(v, l);
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 5; ++x) {
                    const Rgb want = source.value(v, l, x, y), got = image.rgb(x, y);
                    // Half floats keep 11 significant bits; XYZ → RGB mixes three of them.
                    const float tol = 3e-3f * std::max({want.r, want.g, want.b, 0.1f});
                    EXPECT_NEAR(got.r, want.r, tol);
                    EXPECT_NEAR(got.g, want.g, tol);
                    EXPECT_NEAR(got.b, want.b, tol);
                }
        }
    // The file itself holds XYZ, not RGB.
    const Image stored = read_image(folder / "tl011_pl015_tv030_pv090.exr");
    const Xyz want = rgb_to_xyz(source.value(1, 1, 2, 1));
    EXPECT_NEAR(stored.rgb(2, 1).r, want.x, 3e-3 * want.x);
    EXPECT_NEAR(stored.rgb(2, 1).g, want.y, 3e-3 * want.y);
    EXPECT_NEAR(stored.rgb(2, 1).b, want.z, 3e-3 * want.z);
}

TEST(UtiaRead, ConvertsXyzToLinearRgb) {
    TempFolder temp;
    const fs::path folder = temp.path() / "xyz";
    fs::create_directories(folder);
    // D65 white and the XYZ of pure linear red, written by hand as XYZ.
    Image xyz(2, 1, 3);
    xyz.set_rgb(0, 0, Rgb{0.95047f, 1.0f, 1.08883f});
    xyz.set_rgb(1, 0, Rgb{0.4124f, 0.2126f, 0.0193f});
    write_image(folder / "tl000_pl000_tv000_pv000.exr", xyz);
    auto source = utia::open(folder);
    ASSERT_EQ(source->num_views(), 1);
    ASSERT_EQ(source->num_lights(), 1);
    const Image rgb = source->image(0, 0);
    for (float c : {rgb.rgb(0, 0).r, rgb.rgb(0, 0).g, rgb.rgb(0, 0).b}) EXPECT_NEAR(c, 1.0, 2e-3);
    EXPECT_NEAR(rgb.rgb(1, 0).r, 1.0, 2e-3);
    EXPECT_NEAR(rgb.rgb(1, 0).g, 0.0, 2e-3);
    EXPECT_NEAR(rgb.rgb(1, 0).b, 0.0, 2e-3);
}

TEST(UtiaRead, RecognizesUbo81AndOrdersOtherSetsByThetaThenPhi) {
    TempFolder temp;
    Sampling ubo;
    ubo.lights = DirectionSet::ubo81();
    ubo.views = DirectionSet::ubo81().subset({0, 20}, "two");
    utia::write(test_source(ubo, 2, 2), temp.path() / "ubo", "png");
    auto read = utia::open(temp.path() / "ubo");
    EXPECT_EQ(read->sampling().lights.name(), "ubo81");
    EXPECT_EQ(read->num_lights(), 81);
    EXPECT_TRUE(read->sampling().views.same_directions(ubo.views));
    // Light 20 of ubo81 read back is light 20 written (red level identifies light % 7).
    EXPECT_NEAR(read->image(1, 20).rgb(0, 0).r, test_source(ubo, 2, 2).value(1, 20, 0, 0).r, 0.01);

    // A light set given out of order is read back ordered by θ, then φ.
    Sampling shuffled;
    shuffled.lights =
        DirectionSet("shuffled", {Direction::from_degrees(60, 30), Direction::from_degrees(30, 200),
                                  Direction::from_degrees(30, 10)});
    shuffled.views = DirectionSet("v", {Direction::from_degrees(0, 0)});
    utia::write(test_source(shuffled, 2, 2), temp.path() / "shuffled", "png");
    const DirectionSet lights = utia::open(temp.path() / "shuffled")->sampling().lights;
    ASSERT_EQ(lights.size(), 3);
    EXPECT_NEAR(lights[0].phi_deg(), 10, 1e-9);
    EXPECT_NEAR(lights[1].phi_deg(), 200, 1e-9);
    EXPECT_NEAR(lights[2].theta_deg(), 60, 1e-9);
}

TEST(UtiaRead, ChosenViews) {
    TempFolder temp;
    const FunctionSource source = test_source(small_sampling(), 3, 3);
    utia::write(source, temp.path() / "set", "png");
    OpenOptions options;
    options.views = {2, 0};
    auto read = utia::open(temp.path() / "set", options);
    ASSERT_EQ(read->num_views(), 2);
    EXPECT_NEAR(read->sampling().views[1].theta_deg(), 60, 1e-9);
    EXPECT_NEAR(read->image(1, 0).rgb(0, 0).b, source.value(2, 0, 0, 0).b, 0.01);
    EXPECT_THAT(read->info().note, HasSubstr("2 of 3 views"));
    options.views = {3};
    EXPECT_THAT(error_of([&] { utia::open(temp.path() / "set", options); }),
                HasSubstr("view index 3 is out of range"));
}

TEST(UtiaErrors, MissingPair) {
    TempFolder temp;
    const fs::path folder = temp.path() / "set";
    utia::write(test_source(small_sampling(), 3, 3), folder, "png");
    fs::remove(folder / "tl075_pl345_tv060_pv018.png");
    EXPECT_THAT(error_of([&] { utia::open(folder); }),
                AllOf(HasSubstr("set"), HasSubstr("missing image 'tl075_pl345_tv060_pv018.png'"),
                      HasSubstr("14 of 3 views × 5 lights = 15 images present")));
}

TEST(UtiaErrors, MissingLightOfASingleView) {
    // One view: a missing light cannot show as a missing pair; the near-complete ubo81 light
    // set gives it away.
    TempFolder temp;
    const fs::path folder = temp.path() / "one-view";
    const Sampling one_view{DirectionSet::ubo81().subset({0}, "v0"), DirectionSet::ubo81()};
    utia::write(test_source(one_view, 2, 2), folder, "png");
    fs::remove(folder / "tl045_pl020_tv000_pv000.png");
    EXPECT_THAT(
        error_of([&] { utia::open(folder); }),
        AllOf(HasSubstr("one-view"), HasSubstr("80 of the 81 ubo81 directions"),
              HasSubstr("missing light θ=45°, φ=20°"), HasSubstr("tl045_pl020_tv000_pv000.png")));
}

TEST(UtiaErrors, RefusesToOverwrite) {
    TempFolder temp;
    const fs::path folder = temp.path() / "set";
    const FunctionSource source = test_source(small_sampling(), 3, 3);
    utia::write(source, folder, "png");
    const auto before = fs::last_write_time(folder / "tl000_pl000_tv000_pv000.png");
    EXPECT_THAT(error_of([&] { utia::write(source, folder, "exr"); }),
                AllOf(HasSubstr("set"), HasSubstr("exists")));
    EXPECT_FALSE(fs::exists(folder / "tl000_pl000_tv000_pv000.exr"));
    EXPECT_EQ(fs::last_write_time(folder / "tl000_pl000_tv000_pv000.png"), before);
    // Nothing else was left in the parent folder (no temporary).
    int entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(temp.path())) ++entries;
    EXPECT_EQ(entries, 1);
    EXPECT_THAT(error_of([&] { utia::write(source, temp.path() / "other", "tiff"); }),
                HasSubstr("unknown UTIA image format 'tiff'"));
}

TEST(UtiaErrors, DirectionsThatWriteTheSameName) {
    TempFolder temp;
    Sampling s;
    s.lights =
        DirectionSet("l", {Direction::from_degrees(30, 10), Direction::from_degrees(30, 10.0001)});
    s.views = DirectionSet("v", {Direction::from_degrees(0, 0)});
    EXPECT_THAT(error_of([&] { utia::write(test_source(s, 2, 2), temp.path() / "x", "png"); }),
                HasSubstr("lights 0 and 1 of the source both write the name 'tl030_pl010'"));
    EXPECT_FALSE(fs::exists(temp.path() / "x"));
}

TEST(UtiaErrors, MalformedFolders) {
    TempFolder temp;
    const fs::path folder = temp.path() / "set";
    utia::write(test_source(small_sampling(), 3, 3), folder, "png");
    // Unparsable name.
    fs::copy_file(folder / "tl000_pl000_tv000_pv000.png", folder / "tl000_pl000_tv000.png");
    EXPECT_THAT(error_of([&] { utia::open(folder); }),
                AllOf(HasSubstr("tl000_pl000_tv000.png"), HasSubstr("not of the form")));
    fs::remove(folder / "tl000_pl000_tv000.png");
    // The same angles written twice (two digits vs three).
    fs::copy_file(folder / "tl011_pl015_tv000_pv000.png", folder / "tl11_pl15_tv000_pv000.png");
    EXPECT_THAT(error_of([&] { utia::open(folder); }),
                AllOf(HasSubstr("duplicate image"), HasSubstr("tl11_pl15_tv000_pv000.png"),
                      HasSubstr("tl011_pl015_tv000_pv000.png")));
    fs::remove(folder / "tl11_pl15_tv000_pv000.png");
    // A different size.
    fs::remove(folder / "tl011_pl015_tv030_pv090.png");
    write_image(folder / "tl011_pl015_tv030_pv090.png", Image(3, 2, 3, 0.5f));
    EXPECT_THAT(
        error_of([&] { utia::open(folder); }),
        AllOf(HasSubstr("tl011_pl015_tv030_pv090.png"), HasSubstr("3×2"), HasSubstr("3×3")));
    // Mixed formats.
    write_image(folder / "tl011_pl015_tv030_pv090.exr", Image(3, 3, 3, 0.5f));
    EXPECT_THAT(error_of([&] { utia::open(folder); }), HasSubstr("mage in a set of"));
    // Not a folder, empty folder.
    EXPECT_THAT(error_of([&] { utia::open(temp.path() / "nothing"); }), HasSubstr("not a folder"));
    fs::create_directories(temp.path() / "empty");
    EXPECT_FALSE(utia::probe(temp.path() / "empty"));
    EXPECT_THAT(error_of([&] { utia::open(temp.path() / "empty"); }),
                HasSubstr("no UTIA images found"));
}

}  // namespace
}  // namespace btf
