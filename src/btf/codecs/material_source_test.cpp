// SPDX-License-Identifier: MIT
#include "btf/codecs/material_source.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "btf/codecs/codec.h"
#include "btf/io/function_source.h"
#include "btf/io/package.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

using testing::HasSubstr;

// A distinct value for every (texel, view, light, channel).
Rgb pattern(int x, int y, int view, int light) {
    return {0.1f + 0.01f * x + 0.02f * light, 0.2f + 0.03f * y + 0.05f * view,
            0.05f * (x + y) + 0.01f * view * light};
}

// A material that knows its values only through eval_sample (eval is not what is tested).
class PatternMaterial final : public Material {
  public:
    PatternMaterial(int w, int h, Sampling s) : m_w(w), m_h(h), m_s(std::move(s)) {}
    int width() const override { return m_w; }
    int height() const override { return m_h; }
    const Sampling& sampling() const override { return m_s; }
    Rgb eval(const Uv&, const Vec3&, const Vec3&) const override { return {}; }
    Rgb eval_sample(int x, int y, int view, int light) const override {
        return pattern(x, y, view, light);
    }

  private:
    int m_w, m_h;
    Sampling m_s;
};

TEST(MaterialSource, ImagesAreTheMaterialsSamples) {
    const auto material = std::make_shared<PatternMaterial>(7, 5, test::five_views_four_lights());
    const MaterialSource source(material, "test", "somewhere/m.btfpkg");
    EXPECT_EQ(source.width(), 7);
    EXPECT_EQ(source.height(), 5);
    EXPECT_EQ(source.num_views(), 5);
    EXPECT_EQ(source.num_lights(), 4);
    EXPECT_EQ(source.info().format, "btfkit package (test)");
    EXPECT_EQ(source.info().path, "somewhere/m.btfpkg");
    EXPECT_FALSE(source.info().hdr);
    for (int v = 0; v < 5; ++v)
        for (int l = 0; l < 4; ++l) {
            const Image image = source.image(v, l);
            ASSERT_EQ(image.width(), 7);
            ASSERT_EQ(image.height(), 5);
            ASSERT_EQ(image.channels(), 3);
            for (int y = 0; y < 5; ++y)
                for (int x = 0; x < 7; ++x) {
                    const Rgb expected = pattern(x, y, v, l), got = image.rgb(x, y);
                    // Within float rounding: -march=native may contract pattern() into FMAs
                    // differently where it is inlined.
                    EXPECT_FLOAT_EQ(got.r, expected.r);
                    EXPECT_FLOAT_EQ(got.g, expected.g);
                    EXPECT_FLOAT_EQ(got.b, expected.b);
                }
        }
    EXPECT_THAT(
        test::error_of([&] { source.image(5, 0); }),
        HasSubstr("somewhere/m.btfpkg: image (view 5, light 0) outside 5 views × 4 lights"));
}

TEST(MaterialSource, RmseAgainstAKnownDifference) {
    const Sampling s = test::five_views_four_lights();
    const PatternMaterial material(6, 4, s);
    const FunctionSource same(s, 6, 4,
                              [](int v, int l, int x, int y) { return pattern(x, y, v, l); });
    EXPECT_EQ(sample_rmse(same, material), 0.0);

    // Red off by 0.3 and blue by 0.1 everywhere: RMSE = sqrt((0.09 + 0.01) / 3).
    const FunctionSource shifted(s, 6, 4, [](int v, int l, int x, int y) {
        return pattern(x, y, v, l) + Rgb{0.3f, 0.0f, -0.1f};
    });
    EXPECT_NEAR(sample_rmse(shifted, material), std::sqrt(0.1 / 3), 1e-6);

    const FunctionSource wider(
        s, 7, 4, [](int, int, int, int) { return Rgb{}; }, "wider");
    EXPECT_THAT(test::error_of([&] { sample_rmse(wider, material); }),
                HasSubstr("wider: the material is 6×4 texels, the reference 7×4"));
}

TEST(MaterialSource, DecodesAPackageFile) {
    // A rank-one BTF (texel albedo × angular factor) that fmf keeps almost exactly.
    const Sampling s = test::five_views_four_lights();
    const FunctionSource source(s, 8, 6, [](int v, int l, int x, int y) {
        const float a = 0.2f + 0.05f * x + 0.03f * y, g = 0.5f + 0.1f * v + 0.07f * l;
        return Rgb{a * g, 0.8f * a * g, 0.5f * a * g};
    });
    Package package = find_codec("fmf").encode(source, Params::parse({"quantize=f32"}));
    const test::TempFolder dir;
    const auto path = dir.path() / "rank1.btfpkg";
    write_package(path, package);

    const auto decoded = open_package_source(path);
    EXPECT_EQ(decoded->info().format, "btfkit package (fmf)");
    EXPECT_EQ(decoded->info().path, path);
    EXPECT_EQ(decoded->width(), 8);
    EXPECT_EQ(decoded->height(), 6);
    EXPECT_TRUE(decoded->sampling().views.same_directions(s.views));
    EXPECT_LT(sample_rmse(source, decoded->material()), 1e-5);
    // The images hold the same values sample_rmse compared.
    const Image a = source.image(3, 2), b = decoded->image(3, 2);
    for (size_t i = 0; i < a.values().size(); ++i) EXPECT_NEAR(a.values()[i], b.values()[i], 1e-5);

    EXPECT_THAT(test::error_of([&] { open_package_source(dir.path() / "missing.btfpkg"); }),
                HasSubstr("missing.btfpkg"));
}

}  // namespace
}  // namespace btf
