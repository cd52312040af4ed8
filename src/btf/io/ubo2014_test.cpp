// SPDX-License-Identifier: MIT
#include "btf/io/ubo2014.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/SVD>

#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <thread>

#include <unistd.h>

#include "btf/core/color.h"
#include "btf/io/function_source.h"
#include "btf/util/error.h"

namespace btf::ubo2014 {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// ---- fixtures ----------------------------------------------------------------------------------

class Ubo2014Test : public ::testing::Test {
  protected:
    void SetUp() override {
        static std::atomic<int> counter{0};
        m_dir = fs::path(::testing::TempDir()) /
                fmt::format("ubo2014_test_{}_{}", ::getpid(), counter.fetch_add(1));
        fs::create_directories(m_dir);
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(m_dir, ec);
    }
    fs::path path(const std::string& name) const { return m_dir / name; }
    fs::path m_dir;
    int m_count = 0;
};

std::vector<uint8_t> read_bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const fs::path& p, const std::vector<uint8_t>& bytes) {
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}
template <typename T>
void patch(std::vector<uint8_t>& bytes, size_t at, T value) {
    std::memcpy(bytes.data() + at, &value, sizeof(T));
}

// A minimal little-endian byte builder, independent of the library's writer: the tests build
// files with it byte by byte (float64 bodies, FMF bodies, golden expectations).
struct Bytes {
    std::vector<uint8_t> b;
    template <typename T>
    Bytes& put(T v) {
        uint8_t raw[sizeof(T)];
        std::memcpy(raw, &v, sizeof(T));
        b.insert(b.end(), raw, raw + sizeof(T));
        return *this;
    }
    Bytes& text(const std::string& s) {
        b.insert(b.end(), s.begin(), s.end());
        return *this;
    }
    Bytes& fixed80(const std::string& s) {
        std::string padded = s;
        padded.resize(80, '\0');
        return text(padded);
    }
    Bytes& counted(const std::string& s) {
        put<uint32_t>(uint32_t(s.size()));
        return text(s);
    }
    Bytes& half(float v) {
        return put<uint16_t>(Eigen::numext::bit_cast<uint16_t>(Eigen::half(v)));
    }
    size_t size() const { return b.size(); }
};

// Meta block of version 1 (264 bytes) or 2 (268) with empty strings.
void put_meta(Bytes& out, uint32_t version, bool cosine = false) {
    const uint32_t size = version == 1 ? 264 : 268;
    out.put<uint32_t>(size).put<uint32_t>(version);
    out.fixed80("").fixed80("").fixed80("");
    out.put<float>(1).put<float>(1).put<float>(1).put<float>(1);
    if (version > 1) out.put<uint32_t>(cosine ? 1 : 0);
}
void put_directions(Bytes& out, const Sampling& s) {
    out.put<uint32_t>(uint32_t(s.num_views()));
    for (int v = 0; v < s.num_views(); ++v) {
        out.put<float>(float(s.views[v].theta)).put<float>(float(s.views[v].phi));
        out.put<uint32_t>(uint32_t(s.num_lights()));
        for (int l = 0; l < s.num_lights(); ++l)
            out.put<float>(float(s.lights[l].theta)).put<float>(float(s.lights[l].phi));
    }
}

DirectionSet ring_set(const std::string& name, double theta_deg, int count, double offset_deg) {
    std::vector<Direction> dirs = {Direction::from_degrees(0, 0)};
    for (int i = 0; i < count; ++i)
        dirs.push_back(Direction::from_degrees(theta_deg, offset_deg + 360.0 * i / count));
    return DirectionSet(name, dirs);
}

Sampling small_sampling(int views, int lights) {
    std::vector<Direction> v, l;
    for (int i = 0; i < views; ++i) v.push_back(Direction::from_degrees(10.0 * i, 40.0 * i));
    for (int i = 0; i < lights; ++i) l.push_back(Direction::from_degrees(15.0 * i, 100.0 * i));
    return {DirectionSet("v", v), DirectionSet("l", l)};
}

// A DFMF factorization with random factors; model 11's log Y channel stays within [-1.5, 1.5].
Factorization random_factorization(const Sampling& sampling, int width, int height,
                                   std::array<int, 3> k, int32_t model, int scalar_size,
                                   unsigned seed = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uniform(-0.6f, 0.6f);
    Factorization f;
    f.body = Body::kDfmf;
    f.sampling = sampling;
    f.width = width;
    f.height = height;
    f.color_model = model;
    f.meta.measurement_setup = "test dome";
    f.meta.image_sensor = "sensor";
    f.meta.light_source = "led";
    f.meta.ppmm = 12.5f;
    f.meta.rgb_scale_factor = {1.0f, 0.5f, 2.0f};
    f.meta.xml = "<measurement id=\"7\"/>";
    for (int c = 0; c < 3; ++c) {
        Factor factor;
        factor.scalar_size = scalar_size;
        factor.u.resize(sampling.num_images(), k[c]);
        factor.sxv.resize(int64_t(width) * height, k[c]);
        factor.s.resize(k[c]);
        for (int64_t i = 0; i < factor.u.size(); ++i) factor.u.data()[i] = uniform(rng);
        for (int64_t i = 0; i < factor.sxv.size(); ++i) factor.sxv.data()[i] = uniform(rng);
        for (int i = 0; i < k[c]; ++i) factor.s[i] = 4.0f - i;
        if (c == 0 && model == kColorModelRgb) factor.sxv.array() += 0.6f;  // mostly positive
        f.factors.push_back(std::move(factor));
    }
    return f;
}

// The factor product computed here, independently of the library's decoder.
float product(const Factor& f, int64_t row, int64_t texel) {
    double sum = 0;
    for (int k = 0; k < f.components(); ++k) sum += double(f.u(row, k)) * f.sxv(texel, k);
    return float(sum);
}

Rgb expected_dfmf(const Factorization& f, int x, int y, int view, int light) {
    const int64_t row = int64_t(view) * f.sampling.num_lights() + light;
    const int64_t texel = int64_t(y) * f.width + x;
    const std::array<float, 3> c = {product(f.factors[0], row, texel),
                                    product(f.factors[1], row, texel),
                                    product(f.factors[2], row, texel)};
    Rgb rgb = f.color_model == kColorModelLogYUV ? ubo_model11_to_rgb(c) : Rgb{c[0], c[1], c[2]};
    if (f.meta.cosine_flag) rgb = rgb * float(1.0 / std::cos(f.sampling.lights[light].theta));
    return rgb;
}

void expect_near(const Rgb& a, const Rgb& b, float tolerance) {
    const float scale = std::max({1.0f, std::abs(b.r), std::abs(b.g), std::abs(b.b)});
    EXPECT_NEAR(a.r, b.r, tolerance * scale);
    EXPECT_NEAR(a.g, b.g, tolerance * scale);
    EXPECT_NEAR(a.b, b.b, tolerance * scale);
}

std::string error_of(const std::function<void()>& fn) {
    try {
        fn();
    } catch (const Error& e) {
        return e.what();
    }
    return "(no error)";
}

// ---- round trips -------------------------------------------------------------------------------

TEST_F(Ubo2014Test, RoundTripColourModel0Float32) {
    const Factorization f =
        random_factorization(small_sampling(2, 3), 4, 3, {2, 3, 1}, kColorModelRgb, 4);
    const fs::path p = path("rgb.btf");
    write_dfmf(p, f);
    ASSERT_TRUE(probe(p));
    const auto g = read(p);
    EXPECT_EQ(g->body, Body::kDfmf);
    EXPECT_EQ(g->signature(), "!DFMF08FC");
    EXPECT_EQ(g->color_model, kColorModelRgb);
    EXPECT_EQ(g->width, 4);
    EXPECT_EQ(g->height, 3);
    EXPECT_EQ(g->meta.version, 4u);
    EXPECT_EQ(g->meta.measurement_setup, "test dome");
    EXPECT_EQ(g->meta.image_sensor, "sensor");
    EXPECT_EQ(g->meta.light_source, "led");
    EXPECT_EQ(g->meta.ppmm, 12.5f);
    EXPECT_EQ(g->meta.rgb_scale_factor, (std::array<float, 3>{1.0f, 0.5f, 2.0f}));
    EXPECT_EQ(g->meta.xml, "<measurement id=\"7\"/>");
    EXPECT_EQ(g->meta.channel_names, (std::vector<std::string>{"R", "G", "B"}));
    EXPECT_FALSE(g->meta.cosine_flag);
    EXPECT_TRUE(g->sampling.views.same_directions(f.sampling.views));
    EXPECT_TRUE(g->sampling.lights.same_directions(f.sampling.lights));
    ASSERT_EQ(g->factors.size(), 3u);
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(g->factors[c].scalar_size, 4);
        EXPECT_EQ(g->factors[c].u, f.factors[c].u) << c;
        EXPECT_EQ(g->factors[c].sxv, f.factors[c].sxv) << c;
        EXPECT_EQ(g->factors[c].s, f.factors[c].s) << c;
    }
    const auto source = open(p, {});
    EXPECT_EQ(source->info().format, "UBO2014 DFMF");
    EXPECT_TRUE(source->info().hdr);
    for (int v = 0; v < 2; ++v)
        for (int l = 0; l < 3; ++l) {
            const Image image = source->image(v, l);
            ASSERT_EQ(image.width(), 4);
            ASSERT_EQ(image.height(), 3);
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 4; ++x)
                    expect_near(image.rgb(x, y), expected_dfmf(f, x, y, v, l), 1e-5f);
        }
}

TEST_F(Ubo2014Test, RoundTripColourModel11Half) {
    const Factorization f =
        random_factorization(small_sampling(3, 2), 5, 2, {3, 2, 2}, kColorModelLogYUV, 2);
    const fs::path p = path("model11.btf");
    write_dfmf(p, f);
    const auto g = read(p);
    EXPECT_EQ(g->color_model, kColorModelLogYUV);
    // Half storage: every factor entry comes back as the nearest half float.
    Factorization rounded = f;
    for (Factor& factor : rounded.factors) {
        auto to_half = [](float v) { return float(Eigen::half(v)); };
        factor.u = factor.u.unaryExpr(to_half);
        factor.sxv = factor.sxv.unaryExpr(to_half);
        factor.s = factor.s.unaryExpr(to_half);
    }
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(g->factors[c].scalar_size, 2);
        EXPECT_EQ(g->factors[c].u, rounded.factors[c].u) << c;
        EXPECT_EQ(g->factors[c].sxv, rounded.factors[c].sxv) << c;
        EXPECT_EQ(g->factors[c].s, rounded.factors[c].s) << c;
    }
    const auto source = open(p, {});
    for (int v = 0; v < 3; ++v)
        for (int l = 0; l < 2; ++l) {
            const Image image = source->image(v, l);
            for (int y = 0; y < 2; ++y)
                for (int x = 0; x < 5; ++x) {
                    expect_near(image.rgb(x, y), expected_dfmf(rounded, x, y, v, l), 1e-5f);
                    expect_near(g->sample(x, y, v, l), image.rgb(x, y), 1e-6f);
                }
        }
    EXPECT_THAT(source->info().note, HasSubstr("colour model 11"));
}

TEST_F(Ubo2014Test, FactorsThatOverflowTheColourModelAreRefusedWhereTheyEnter) {
    // One legal half float of 65504 in the log-Y factor: exp() of the product overflows, which
    // used to compress into an all-NaN package. The source refuses the image instead.
    Factorization f =
        random_factorization(small_sampling(3, 2), 5, 2, {3, 2, 2}, kColorModelLogYUV, 2);
    f.factors[0].u(4, 0) = 65504.0f;
    f.factors[0].sxv.col(0).setConstant(0.5f);
    const fs::path p = path("overflow.btf");
    write_dfmf(p, f);
    const auto source = open(p, {});
    Image image;
    EXPECT_NO_THROW(source->read_image(0, 0, image));  // rows without the huge value decode
    EXPECT_THAT(error_of([&] { source->read_image(2, 0, image); }),  // row 4 = view 2, light 0
                AllOf(HasSubstr("overflow.btf"), HasSubstr("image (view 2, light 0)"),
                      HasSubstr("non-finite value")));
}

TEST_F(Ubo2014Test, CosineFlagIsDividedOut) {
    Factorization f =
        random_factorization(small_sampling(2, 4), 3, 3, {2, 2, 2}, kColorModelLogYUV, 4);
    f.meta.cosine_flag = true;
    const fs::path p = path("cos.btf");
    write_dfmf(p, f);
    const auto g = read(p);
    EXPECT_TRUE(g->meta.cosine_flag);
    Factorization plain = f;
    plain.meta.cosine_flag = false;
    for (int l = 0; l < 4; ++l) {
        const float cosine = float(std::cos(f.sampling.lights[l].theta));
        for (int y = 0; y < 3; ++y)
            for (int x = 0; x < 3; ++x) {
                const Rgb stored = plain.sample(x, y, 1, l);
                expect_near(g->sample(x, y, 1, l), stored * (1.0f / cosine), 1e-5f);
                expect_near(g->sample(x, y, 1, l), expected_dfmf(f, x, y, 1, l), 1e-5f);
            }
    }
}

TEST_F(Ubo2014Test, ReadsFloat64BodyWrittenByteByByte) {
    const Sampling s = small_sampling(1, 2);
    const int w = 2, h = 2, k = 2;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> uniform(-1, 1);
    Bytes out;
    out.text("!DFMF08FC");
    put_meta(out, 2);
    put_directions(out, s);
    out.put<uint32_t>(w).put<uint32_t>(h);
    out.put<uint32_t>(k).put<int32_t>(0);
    for (int i = 0; i < 3; ++i) out.put<float>(0);
    for (int i = 0; i < 9; ++i) out.put<float>(i % 4 == 0 ? 1.0f : 0.0f);
    std::vector<Eigen::MatrixXd> us, vs;
    for (int c = 0; c < 3; ++c) {
        out.put<uint8_t>(8).put<uint32_t>(k).put<uint32_t>(2).put<uint32_t>(4);
        out.put<double>(2.0).put<double>(1.0);
        Eigen::MatrixXd u(2, k), sxv(4, k);
        for (int i = 0; i < 2; ++i)
            for (int j = 0; j < k; ++j) out.put<double>(u(i, j) = uniform(rng));
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < k; ++j) out.put<double>(sxv(i, j) = uniform(rng));
        us.push_back(u);
        vs.push_back(sxv);
    }
    const fs::path p = path("f64.btf");
    write_bytes(p, out.b);
    const auto g = read(p);
    EXPECT_EQ(g->meta.version, 2u);
    EXPECT_TRUE(g->meta.channel_names.empty());
    EXPECT_EQ(g->factors[0].scalar_size, 8);
    const auto source = open(p, {});
    for (int l = 0; l < 2; ++l) {
        const Image image = source->image(0, l);
        for (int t = 0; t < 4; ++t)
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(image.at(t % 2, t / 2, c), (us[c].row(l) * vs[c].row(t).transpose())(0),
                            1e-6);
    }
}

// ---- golden bytes ------------------------------------------------------------------------------

TEST_F(Ubo2014Test, GoldenBytesOfTinyDfmf) {
    Factorization f;
    f.sampling = {DirectionSet("v", {Direction{0.0, 0.0}}),
                  DirectionSet("l", {Direction{0.0, 0.0}, Direction{0.5, 1.0}})};
    f.width = 2;
    f.height = 1;
    f.color_model = kColorModelLogYUV;
    f.meta.measurement_setup = "dome";
    f.meta.image_sensor = "cam";
    f.meta.light_source = "led";
    f.meta.ppmm = 10.0f;
    f.meta.rgb_scale_factor = {1.0f, 2.0f, 3.0f};
    f.meta.xml = "<m/>";
    for (int c = 0; c < 3; ++c) {
        Factor factor;
        factor.scalar_size = c == 1 ? 2 : 4;
        factor.s = Eigen::VectorXf::Constant(1, 3.0f);
        factor.u.resize(2, 1);
        factor.u << 0.5f, -0.25f;
        factor.sxv.resize(2, 1);
        factor.sxv << 1.0f + c, 2.0f;
        f.factors.push_back(factor);
    }
    const fs::path p = path("golden.btf");
    write_dfmf(p, f);
    const std::vector<uint8_t> bytes = read_bytes(p);

    // Spot checks with literal bytes at fixed offsets.
    ASSERT_GE(bytes.size(), 400u);
    EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + 9), "!DFMF08FC");
    // meta size = 264 + 4 (cosine) + 4 + 4 (XML) + 4 + 3 × (4 + 1) (channel names) = 295
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + 9, bytes.begin() + 17),
              (std::vector<uint8_t>{0x27, 0x01, 0, 0, 4, 0, 0, 0}));
    EXPECT_EQ(std::string(bytes.begin() + 17, bytes.begin() + 21), "dome");
    EXPECT_EQ(bytes[21], 0);
    EXPECT_EQ(std::string(bytes.begin() + 97, bytes.begin() + 100), "cam");
    EXPECT_EQ(std::string(bytes.begin() + 177, bytes.begin() + 180), "led");
    // ppmm 10.0f = 0x41200000 at 9 + 248
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + 257, bytes.begin() + 261),
              (std::vector<uint8_t>{0x00, 0x00, 0x20, 0x41}));
    // cosine flag at 9 + 264, XML length + "<m/>" after it
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + 273, bytes.begin() + 281),
              (std::vector<uint8_t>{0, 0, 0, 0, 4, 0, 0, 0}));
    EXPECT_EQ(std::string(bytes.begin() + 281, bytes.begin() + 285), "<m/>");
    // channel count 3, then "R"
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + 285, bytes.begin() + 294),
              (std::vector<uint8_t>{3, 0, 0, 0, 1, 0, 0, 0, 'R'}));
    const size_t dirs = 9 + 295;  // = 304
    // nV = 1, view (0, 0), nL = 2, light 0 (0, 0), light 1 (0.5f = 0x3f000000, 1.0f = 0x3f800000)
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + dirs, bytes.begin() + dirs + 32),
              (std::vector<uint8_t>{1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,    2, 0, 0,    0,
                                    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x3f, 0, 0, 0x80, 0x3f}));
    const size_t wh = dirs + 32;  // width 2, height 1
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + wh, bytes.begin() + wh + 8),
              (std::vector<uint8_t>{2, 0, 0, 0, 1, 0, 0, 0}));
    const size_t body = wh + 8;  // max K = 1, colour model 11
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + body, bytes.begin() + body + 8),
              (std::vector<uint8_t>{1, 0, 0, 0, 11, 0, 0, 0}));
    const size_t channel0 = body + 8 + 12 + 36;  // scalar size 4, K 1, rows 2, cols 2
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + channel0, bytes.begin() + channel0 + 13),
              (std::vector<uint8_t>{4, 1, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0}));
    // S = 3.0f, U = (0.5, -0.25), SxV = (1, 2)
    EXPECT_EQ(std::vector<uint8_t>(bytes.begin() + channel0 + 13, bytes.begin() + channel0 + 33),
              (std::vector<uint8_t>{0,    0,    0x40, 0x40, 0,    0,    0, 0x3f, 0, 0,
                                    0x80, 0xbe, 0,    0,    0x80, 0x3f, 0, 0,    0, 0x40}));
    const size_t channel1 = channel0 + 33;  // half: S 3 = 0x4200, U 0.5 = 0x3800, −0.25 = 0xb400
    EXPECT_EQ(
        std::vector<uint8_t>(bytes.begin() + channel1, bytes.begin() + channel1 + 23),
        (std::vector<uint8_t>{2, 1,    0,    0,    0,    2,    0,    0,    0,    2,    0,   0,
                              0, 0x00, 0x42, 0x00, 0x38, 0x00, 0xb4, 0x00, 0x40, 0x00, 0x40}));

    // The whole file, byte for byte, from the independent builder.
    Bytes expected;
    expected.text("!DFMF08FC").put<uint32_t>(295).put<uint32_t>(4);
    expected.fixed80("dome").fixed80("cam").fixed80("led");
    expected.put<float>(10).put<float>(1).put<float>(2).put<float>(3);
    expected.put<uint32_t>(0).counted("<m/>");
    expected.put<uint32_t>(3).counted("R").counted("G").counted("B");
    expected.put<uint32_t>(1).put<float>(0).put<float>(0).put<uint32_t>(2);
    expected.put<float>(0).put<float>(0).put<float>(0.5f).put<float>(1.0f);
    expected.put<uint32_t>(2).put<uint32_t>(1);
    expected.put<uint32_t>(1).put<int32_t>(11);
    for (int i = 0; i < 3; ++i) expected.put<float>(0);
    for (int i = 0; i < 9; ++i) expected.put<float>(i % 4 == 0 ? 1.0f : 0.0f);
    for (int c = 0; c < 3; ++c) {
        const int ss = c == 1 ? 2 : 4;
        expected.put<uint8_t>(uint8_t(ss)).put<uint32_t>(1).put<uint32_t>(2).put<uint32_t>(2);
        for (float v : {3.0f, 0.5f, -0.25f, 1.0f + c, 2.0f}) {
            if (ss == 2)
                expected.half(v);
            else
                expected.put<float>(v);
        }
    }
    EXPECT_EQ(bytes, expected.b);
}

TEST_F(Ubo2014Test, MetaSizeWhoseLowByteIsRIsNotMistakenForTheRotationSignature) {
    Factorization f = random_factorization(small_sampling(1, 2), 2, 2, {1, 1, 1}, 0, 4);
    f.meta.version = 3;
    f.meta.xml = std::string(66, 'x');  // size 264 + 4 + 4 + 66 = 338 = 0x152: low byte 'R'
    const fs::path p = path("r.btf");
    write_dfmf(p, f);
    const std::vector<uint8_t> bytes = read_bytes(p);
    ASSERT_EQ(bytes[9], 'R');
    const auto g = read(p);
    EXPECT_EQ(g->signature(), "!DFMF08FC");
    EXPECT_EQ(g->meta.xml, f.meta.xml);
    EXPECT_EQ(g->factors[2].sxv, f.factors[2].sxv);
}

TEST_F(Ubo2014Test, RotationBlockRoundTrips) {
    Factorization f = random_factorization(small_sampling(2, 2), 2, 1, {1, 2, 1}, 0, 4);
    f.rotation_block = true;
    f.rotations = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, -1, 0, 1, 0, 0, 0, 0, 1}};
    const fs::path p = path("rot.btf");
    write_dfmf(p, f);
    const std::vector<uint8_t> bytes = read_bytes(p);
    EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + 10), "!DFMF08FCR");
    const auto g = read(p);
    EXPECT_TRUE(g->rotation_block);
    EXPECT_EQ(g->rotations, f.rotations);
    EXPECT_EQ(g->factors[1].u, f.factors[1].u);
}

// ---- FMF ---------------------------------------------------------------------------------------

TEST_F(Ubo2014Test, FmfBodyBuiltByteByByteDecodes) {
    const Sampling s = small_sampling(2, 2);
    const int w = 2, h = 2, nc = 3;
    const std::vector<float> u = {0.10f, 0.20f, 0.30f, -0.10f, 0.05f,  0.00f,
                                  0.40f, 0.35f, 0.30f, -0.50f, -0.40f, -0.30f};  // 12 rows, K = 1
    const std::vector<float> sxv = {1.0f, 2.0f, -1.0f, 0.5f};                    // 4 texels
    for (uint32_t drr : {0u, 1u}) {
        Bytes out;
        out.text("!FMF12FCER");
        put_meta(out, 1);
        put_directions(out, s);
        out.put<uint32_t>(w).put<uint32_t>(h);
        out.put<uint32_t>(1);
        for (int i = 0; i < 9; ++i) out.put<float>(float(i));
        out.put<uint8_t>(2).put<uint32_t>(drr);
        out.put<uint32_t>(1).put<uint32_t>(2).half(0.25f).half(-0.5f);  // 1×2 height map
        out.put<uint32_t>(1).put<uint8_t>(4).put<uint32_t>(1);          // K, scalar size, K
        out.put<uint32_t>(12).put<uint32_t>(4);                         // rows nL·nV·nC, cols
        out.put<float>(2.0f);
        for (float v : u) out.put<float>(v);
        for (float v : sxv) out.put<float>(v);
        const fs::path p = path(fmt::format("fmf{}.btf", drr));
        write_bytes(p, out.b);
        ASSERT_TRUE(probe(p));
        const auto g = read(p);
        EXPECT_EQ(g->body, Body::kFmf);
        EXPECT_EQ(g->signature(), "!FMF12FCER");
        EXPECT_EQ(g->meta.version, 1u);
        EXPECT_EQ(g->fmf_header_version, 2);
        EXPECT_EQ(g->dynamic_range_reduction, drr);
        EXPECT_EQ(g->height_map, (std::vector<float>{0.25f, -0.5f}));
        ASSERT_EQ(g->rotations.size(), 1u);
        EXPECT_EQ(g->rotations[0][8], 8.0f);
        const auto source = open(p, {});
        EXPECT_EQ(source->info().format, "UBO2014 FMF");
        for (int v = 0; v < 2; ++v)
            for (int l = 0; l < 2; ++l) {
                const Image image = source->image(v, l);
                for (int t = 0; t < 4; ++t)
                    for (int c = 0; c < nc; ++c) {
                        const float x = u[(v * 2 + l) * nc + c] * sxv[t];
                        const float expected = drr ? std::exp(x) - 1e-5f : x;
                        EXPECT_NEAR(image.at(t % w, t / w, c), expected, 1e-6f)
                            << v << " " << l << " " << t << " " << c;
                    }
            }
    }
}

TEST_F(Ubo2014Test, MalformedFmfBodies) {
    const Sampling s = small_sampling(1, 2);
    // header version, K, second K, rows, extra trailing bytes
    auto build = [&](uint8_t version, uint32_t k, uint32_t k2, uint32_t rows, size_t trailing) {
        Bytes out;
        out.text("!FMF12FCE");
        put_meta(out, 1);
        put_directions(out, s);
        out.put<uint32_t>(2).put<uint32_t>(1);
        out.put<uint8_t>(version);
        if (version >= 1) out.put<uint32_t>(0);
        out.put<uint32_t>(k).put<uint8_t>(4).put<uint32_t>(k2);
        out.put<uint32_t>(rows).put<uint32_t>(2);
        for (uint32_t i = 0; i < k + rows * k + 2 * k; ++i) out.put<float>(0.5f);
        for (size_t i = 0; i < trailing; ++i) out.put<uint8_t>(0);
        const fs::path p = path(fmt::format("fmf_bad_{}.btf", m_count++));
        write_bytes(p, out.b);
        const std::string e = error_of([&] { read(p); });
        if (e != "(no error)") {
            EXPECT_THAT(e, HasSubstr(p.string()));
        }
        return e;
    };
    EXPECT_EQ(build(1, 1, 1, 6, 0), "(no error)");
    EXPECT_THAT(build(1, 1, 2, 6, 0), HasSubstr("the FMF body declares K = 1 and then K = 2"));
    EXPECT_THAT(build(1, 1, 1, 2, 0),
                HasSubstr("the FMF body declares 2 rows but views × lights × channels = 6"));
    EXPECT_THAT(build(3, 1, 1, 6, 0), HasSubstr("unsupported FMF header version 3"));
    EXPECT_THAT(build(0, 1, 1, 6, 2), HasSubstr("2 trailing bytes after the FMF body"));
}

TEST_F(Ubo2014Test, NewerMetaVersionsSkipUnknownFields) {
    const Sampling s = small_sampling(1, 1);
    Bytes out;
    out.text("!DFMF08FC");
    // version 5: the version 4 fields (XML "", channels "R", "G", "B") plus 6 unknown bytes
    const uint32_t size = 264 + 4 + 4 + 4 + 3 * 5 + 6;
    out.put<uint32_t>(size).put<uint32_t>(5).fixed80("new").fixed80("").fixed80("");
    out.put<float>(1).put<float>(1).put<float>(1).put<float>(1).put<uint32_t>(0).counted("");
    out.put<uint32_t>(3).counted("R").counted("G").counted("B");
    for (int i = 0; i < 6; ++i) out.put<uint8_t>(0xee);
    put_directions(out, s);
    out.put<uint32_t>(1).put<uint32_t>(1);
    out.put<uint32_t>(1).put<int32_t>(0);
    for (int i = 0; i < 12; ++i) out.put<float>(0);
    for (int c = 0; c < 3; ++c) {
        out.put<uint8_t>(4).put<uint32_t>(1).put<uint32_t>(1).put<uint32_t>(1);
        out.put<float>(1).put<float>(2).put<float>(0.25f * (c + 1));
    }
    const fs::path p = path("v5.btf");
    write_bytes(p, out.b);
    const auto g = read(p);
    EXPECT_EQ(g->meta.version, 5u);
    EXPECT_EQ(g->meta.skipped_bytes, 6u);
    EXPECT_EQ(g->meta.measurement_setup, "new");
    expect_near(g->sample(0, 0, 0, 0), Rgb{0.5f, 1.0f, 1.5f}, 1e-7f);
}

TEST_F(Ubo2014Test, WriterRefusesFmfAndHalfOverflow) {
    Factorization f = random_factorization(small_sampling(1, 2), 2, 1, {1, 1, 1}, 0, 2);
    f.factors[2].sxv(1, 0) = 70000.0f;
    const fs::path p = path("overflow.btf");
    const std::string e = error_of([&] { write_dfmf(p, f); });
    EXPECT_THAT(e, HasSubstr(p.string()));
    EXPECT_THAT(e, HasSubstr("SxV matrix of channel 2 holds 70000 at row 1, column 0, beyond the "
                             "half-float range"));
    EXPECT_FALSE(fs::exists(p));
    f.body = Body::kFmf;
    EXPECT_THAT(error_of([&] { write_dfmf(p, f); }), HasSubstr("DFMF bodies only"));
}

// ---- source and material -----------------------------------------------------------------------

TEST_F(Ubo2014Test, ViewSubsetAndThreadSafeReads) {
    const Factorization f =
        random_factorization(small_sampling(4, 3), 6, 5, {3, 2, 2}, kColorModelLogYUV, 4);
    const fs::path p = path("views.btf");
    write_dfmf(p, f);
    OpenOptions options;
    options.views = {3, 1};
    const auto source = open(p, options);
    ASSERT_EQ(source->num_views(), 2);
    EXPECT_NEAR(source->sampling().views[0].theta, f.sampling.views[3].theta, 1e-6);
    const auto g = read(p);
    for (int l = 0; l < 3; ++l) {
        const Image image = source->image(0, l);
        expect_near(image.rgb(2, 4), g->sample(2, 4, 3, l), 1e-6f);
        expect_near(source->image(1, l).rgb(5, 0), g->sample(5, 0, 1, l), 1e-6f);
    }
    options.views = {4};
    const std::string e = error_of([&] { open(p, options); });
    EXPECT_THAT(e, HasSubstr(p.string()));
    EXPECT_THAT(e, HasSubstr("view index 4 out of range"));
    options.views = {1, 1};
    EXPECT_THAT(error_of([&] { open(p, options); }), HasSubstr("view index 1 given twice"));

    const auto all = open(p, {});
    std::vector<Image> reference;
    for (int i = 0; i < 12; ++i) reference.push_back(all->image(i / 3, i % 3));
    std::atomic<int> mismatches{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&, t] {
            Image image;
            for (int round = 0; round < 20; ++round)
                for (int i = 0; i < 12; ++i) {
                    const int j = (i + t * 5) % 12;
                    all->read_image(j / 3, j % 3, image);
                    if (image.values() != reference[j].values()) ++mismatches;
                }
        });
    for (auto& t : threads) t.join();
    EXPECT_EQ(mismatches.load(), 0);
    EXPECT_THAT(error_of([&] { all->image(0, 3); }), HasSubstr("out of range"));
}

// make_material: the RGB-interpolating material that files with the cosine flag are opened as
// (the others are the fmf evaluator of their factors: codecs/dfmf_export_test.cpp).
class Ubo2014MaterialTest : public Ubo2014Test {
  protected:
    Factorization make() const {
        const Sampling s{ring_set("views", 35, 6, 0), ring_set("lights", 50, 8, 22.5)};
        Factorization f = random_factorization(s, 4, 3, {2, 2, 2}, kColorModelLogYUV, 4, 9);
        f.meta.cosine_flag = true;
        return f;
    }
};

TEST_F(Ubo2014MaterialTest, EvalEqualsEvalSampleAtSamplesAndTexelCentres) {
    const fs::path p = path("material.btf");
    write_dfmf(p, make());
    const auto material = make_material(read(p));
    ASSERT_EQ(material->width(), 4);
    ASSERT_EQ(material->height(), 3);
    const Sampling& s = material->sampling();
    for (int v = 0; v < s.num_views(); ++v)
        for (int l = 0; l < s.num_lights(); ++l)
            for (int y = 0; y < 3; ++y)
                for (int x = 0; x < 4; ++x) {
                    const Uv uv{(x + 0.5) / 4, (y + 0.5) / 3};
                    const Rgb exact = material->eval_sample(x, y, v, l);
                    expect_near(material->eval(uv, s.lights.vector(l), s.views.vector(v)), exact,
                                1e-5f);
                }
    // Half way between two texel centres (same row, exact directions): the average.
    const Rgb a = material->eval_sample(1, 2, 3, 4), b = material->eval_sample(2, 2, 3, 4);
    expect_near(material->eval({2.0 / 4, 2.5 / 3}, s.lights.vector(4), s.views.vector(3)),
                (a + b) * 0.5f, 1e-5f);
}

TEST_F(Ubo2014MaterialTest, EvalIsContinuous) {
    const auto material = make_material(std::make_shared<Factorization>(make()));
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> unit(0, 1);
    auto random_dir = [&] {
        const double theta = 1.2 * unit(rng), phi = 2 * kPi * unit(rng);
        return Direction{theta, phi};
    };
    for (int i = 0; i < 300; ++i) {
        const Uv uv{unit(rng), unit(rng)};
        const Direction wi = random_dir(), wo = random_dir();
        const double d = 1e-6;
        const Rgb here = material->eval(uv, wi.vector(), wo.vector());
        const Rgb near =
            material->eval({uv.u + d, uv.v - d}, Direction{wi.theta + d, wi.phi - d}.vector(),
                           Direction{wo.theta - d, wo.phi + d}.vector());
        const float scale = std::max(1.0f, std::abs(here.r) + std::abs(here.g) + std::abs(here.b));
        EXPECT_LT(std::abs(here.r - near.r) + std::abs(here.g - near.g) + std::abs(here.b - near.b),
                  1e-3f * scale)
            << i;
    }
}

// ---- the in-memory factorization ---------------------------------------------------------------

FunctionSource analytic_source(Sampling s, int w, int h) {
    const Sampling directions = s;
    return FunctionSource(std::move(s), w, h, [directions](int view, int light, int x, int y) {
        const double cl = directions.lights.vector(light).z, cv = directions.views.vector(view).z;
        return Rgb{float(0.3 + 0.2 * std::sin(x + 2.0 * y + view) * cl),
                   float(0.2 + 0.1 * cv * std::cos(0.5 * x - y + light)),
                   float(0.1 + 0.05 * (x + 1) * cl * cv + 0.01 * light)};
    });
}

TEST_F(Ubo2014Test, FullRankFactorizationReproducesTheSource) {
    const FunctionSource source = analytic_source(small_sampling(3, 4), 3, 2);
    for (int32_t model : {kColorModelRgb, kColorModelLogYUV})
        for (bool cosine : {false, true}) {
            FactorizeOptions options;
            options.color_model = model;
            options.components = 100;  // clamped to min(12, 6) = 6
            options.meta.cosine_flag = cosine;
            const fs::path p = path(fmt::format("full{}{}.btf", model, cosine));
            write_dfmf(p, source, options);
            const auto g = read(p);
            EXPECT_EQ(g->factors[0].components(), 6);
            EXPECT_EQ(g->meta.cosine_flag, cosine);
            const auto back = open(p, {});
            for (int v = 0; v < 3; ++v)
                for (int l = 0; l < 4; ++l) {
                    const Image a = source.image(v, l), b = back->image(v, l);
                    for (int y = 0; y < 2; ++y)
                        for (int x = 0; x < 3; ++x) expect_near(b.rgb(x, y), a.rgb(x, y), 1e-4f);
                }
        }
}

TEST_F(Ubo2014Test, TruncatedFactorizationIsEckartYoungOptimal) {
    const FunctionSource source = analytic_source(small_sampling(4, 5), 4, 4);
    FactorizeOptions options;
    options.color_model = kColorModelRgb;
    options.components = 3;
    const Factorization f = factorize(source, options);
    for (int c = 0; c < 3; ++c) {
        Eigen::MatrixXd a(20, 16);
        for (int row = 0; row < 20; ++row) {
            const Image image = source.image(row / 5, row % 5);
            for (int t = 0; t < 16; ++t) a(row, t) = image.at(t % 4, t / 4, c);
        }
        const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a);
        const double tail = svd.singularValues().tail(16 - 3).norm();
        const Eigen::MatrixXd approx =
            f.factors[c].u.cast<double>() * f.factors[c].sxv.cast<double>().transpose();
        EXPECT_NEAR((a - approx).norm(), tail, 1e-4 + 1e-3 * tail) << c;
        for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(f.factors[c].s[k], svd.singularValues()[k], 1e-4) << c;
    }
}

TEST_F(Ubo2014Test, FactorizationRefusesLargeSources) {
    const FunctionSource source = analytic_source(small_sampling(3, 4), 5, 5);
    FactorizeOptions options;
    options.max_samples = 200;
    EXPECT_THAT(error_of([&] { factorize(source, options); }),
                HasSubstr("12 images × 25 texels = 300 samples per channel exceed the exact "
                          "in-memory factorization's limit of 200"));
    options.max_samples = kMaxFactorizeSamples;
    options.color_model = 3;
    EXPECT_THAT(error_of([&] { factorize(source, options); }),
                HasSubstr("cannot factorize into colour model 3"));
}

// ---- malformed input ---------------------------------------------------------------------------

// The standard file for the malformed-input tests and where its parts lie.
struct Layout {
    size_t meta = 9, meta_size = 0, dirs = 0, wh = 0, body = 0;
    std::array<size_t, 3> channel{}, s{}, u{}, sxv{};
};

class Ubo2014MalformedTest : public Ubo2014Test {
  protected:
    void SetUp() override {
        Ubo2014Test::SetUp();
        m_f = random_factorization(small_sampling(2, 3), 4, 3, {2, 2, 2}, kColorModelLogYUV, 4);
        m_good = path("good.btf");
        write_dfmf(m_good, m_f);
        m_bytes = read_bytes(m_good);
        Layout& l = m_layout;
        l.meta_size = 264 + 4 + 4 + m_f.meta.xml.size() + 4 + 3 * 5;
        l.dirs = 9 + l.meta_size;
        l.wh = l.dirs + 4 + 2 * (12 + 8 * 3);
        l.body = l.wh + 8;
        size_t at = l.body + 56;
        for (int c = 0; c < 3; ++c) {
            l.channel[c] = at;
            l.s[c] = at + 13;
            l.u[c] = l.s[c] + 2 * 4;
            l.sxv[c] = l.u[c] + 6 * 2 * 4;
            at = l.sxv[c] + 12 * 2 * 4;
        }
        ASSERT_EQ(at, m_bytes.size());
    }
    // Writes `bytes` to a fresh file and returns the error text of reading it.
    std::string read_error(const std::vector<uint8_t>& bytes) {
        const fs::path p = path(fmt::format("bad{}.btf", m_count++));
        write_bytes(p, bytes);
        const std::string e = error_of([&] { read(p); });
        EXPECT_THAT(e, HasSubstr(p.string())) << "message must name the file";
        return e;
    }
    std::vector<uint8_t> truncated(size_t length) const {
        return {m_bytes.begin(), m_bytes.begin() + length};
    }

    Factorization m_f;
    fs::path m_good;
    std::vector<uint8_t> m_bytes;
    Layout m_layout;
};

TEST_F(Ubo2014MalformedTest, LayoutAssumptionsHold) {
    EXPECT_NO_THROW(read(m_good));
    uint32_t meta_size;
    std::memcpy(&meta_size, &m_bytes[9], 4);
    EXPECT_EQ(meta_size, m_layout.meta_size);
}

TEST_F(Ubo2014MalformedTest, WrongAndUnsupportedSignatures) {
    std::vector<uint8_t> b = m_bytes;
    std::memcpy(b.data(), "!XYZW08FC", 9);
    EXPECT_THAT(read_error(b), HasSubstr("not a Bonn UBO .btf file: it starts with '!XYZW08FC"));
    EXPECT_THAT(read_error({}), HasSubstr("not a Bonn UBO .btf file"));
    for (const std::string sig : {"!FMF06FC", "!PVF06FC", "!BDIF06R2!", "!FMF06FCR"}) {
        std::vector<uint8_t> u(sig.begin(), sig.end());
        u.insert(u.end(), m_bytes.begin() + 9, m_bytes.end());
        EXPECT_THAT(read_error(u), HasSubstr("unsupported UBO .btf signature '" + sig + "'"));
        write_bytes(path("probe.btf"), u);
        EXPECT_TRUE(probe(path("probe.btf"))) << sig;
    }
    write_bytes(path("text.btf"), {'h', 'e', 'l', 'l', 'o'});
    EXPECT_FALSE(probe(path("text.btf")));
    EXPECT_FALSE(probe(m_dir));
    EXPECT_THAT(error_of([&] { read(path("missing.btf")); }), HasSubstr("no such file"));
}

TEST_F(Ubo2014MalformedTest, TruncatedAtSeveralPoints) {
    EXPECT_THAT(read_error(truncated(100)),
                HasSubstr(fmt::format("byte 9: meta block declares {} bytes but the file ends "
                                      "after 91",
                                      m_layout.meta_size)));
    EXPECT_THAT(read_error(truncated(m_layout.dirs + 2)), HasSubstr("view count needs 4 bytes"));
    EXPECT_THAT(read_error(truncated(m_layout.dirs + 4 + 12 + 20)),
                HasSubstr(fmt::format("byte {}: view 0 of 2 declares 3 light directions (24 "
                                      "bytes) but the file ends after 20 bytes",
                                      m_layout.dirs + 16)));
    EXPECT_THAT(read_error(truncated(m_layout.wh + 6)), HasSubstr("height needs 4 bytes"));
    EXPECT_THAT(read_error(truncated(m_layout.s[0] + 4)),
                HasSubstr("S of channel 0 declares 2 values but the file ends after 1"));
    EXPECT_THAT(read_error(truncated(m_layout.u[0] + 3 * 8 + 5)),
                HasSubstr(fmt::format("byte {}: U matrix of channel 0 declares 6×2 rows×cols but "
                                      "file ends after 3 rows",
                                      m_layout.u[0])));
    EXPECT_THAT(read_error(truncated(m_layout.sxv[2] + 5 * 8 + 1)),
                HasSubstr(fmt::format("byte {}: SxV matrix of channel 2 declares 12×2 rows×cols "
                                      "but file ends after 5 rows",
                                      m_layout.sxv[2])));
    EXPECT_THAT(read_error(truncated(m_bytes.size() - 1)),
                HasSubstr("SxV matrix of channel 2 declares 12×2 rows×cols but file ends after "
                          "11 rows"));
}

TEST_F(Ubo2014MalformedTest, SizeFieldsExceedingTheFile) {
    std::vector<uint8_t> b = m_bytes;
    patch<uint32_t>(b, 9 + 268, 1000000000u);  // XML length
    EXPECT_THAT(read_error(b), HasSubstr("XML string of 1000000000 bytes reaches beyond them"));
    b = m_bytes;
    patch<uint32_t>(b, 9, 1u << 30);  // meta size
    EXPECT_THAT(read_error(b), HasSubstr("byte 9: meta block declares 1073741824 bytes but the "
                                         "file ends after"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.dirs, 60000u);
    EXPECT_THAT(read_error(b), HasSubstr("directions of 60000 views needs 720000 bytes"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.dirs, 0x7fffffffu);
    EXPECT_THAT(read_error(b), HasSubstr("declares 2147483647 views (expected 1..65536)"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.dirs + 12, 50000u);  // light count of view 0
    EXPECT_THAT(read_error(b), HasSubstr("view 0 of 2 declares 50000 light directions"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.wh, 1u << 30);
    EXPECT_THAT(read_error(b), HasSubstr("declares 1073741824×3 texels"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.wh, 5u);
    EXPECT_THAT(read_error(b),
                HasSubstr(fmt::format("byte {}: channel 0 declares 12 columns but width × "
                                      "height = 15",
                                      m_layout.channel[0])));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.channel[1] + 1, 1000u);  // K of channel 1
    EXPECT_THAT(read_error(b), HasSubstr("channel 1 declares K = 1000 but the DFMF header's "
                                         "maximum"));
    patch<uint32_t>(b, m_layout.body, 1000u);  // max K too
    EXPECT_THAT(read_error(b), HasSubstr("channel 1 declares K = 1000 components, more than "
                                         "min(rows, columns) = 6 allows"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.channel[2] + 5, 7u);  // rows of channel 2
    EXPECT_THAT(read_error(b), HasSubstr("channel 2 declares 7 rows but views × lights = 6"));
    b = m_bytes;
    patch<uint8_t>(b, m_layout.channel[0], 3);
    EXPECT_THAT(read_error(b), HasSubstr("channel 0 has scalar size 3"));
    b = m_bytes;
    patch<uint32_t>(b, m_layout.body, 1u);  // max K 1 < K = 2
    EXPECT_THAT(read_error(b), HasSubstr("but the DFMF header's maximum"));
}

TEST_F(Ubo2014MalformedTest, TrailingBytes) {
    std::vector<uint8_t> b = m_bytes;
    b.insert(b.end(), {1, 2, 3});
    EXPECT_THAT(
        read_error(b),
        HasSubstr(fmt::format("byte {}: 3 trailing bytes after the DFMF body", m_bytes.size())));
}

TEST_F(Ubo2014MalformedTest, NaNAndInfInFactors) {
    std::vector<uint8_t> b = m_bytes;
    const size_t at = m_layout.u[1] + (1 * 2 + 0) * 4;  // U of channel 1, row 1, column 0
    patch<float>(b, at, std::numeric_limits<float>::quiet_NaN());
    EXPECT_THAT(read_error(b), HasSubstr(fmt::format("byte {}: U matrix of channel 1 holds NaN at "
                                                     "row 1, column 0",
                                                     at)));
    b = m_bytes;
    const size_t at2 = m_layout.sxv[0] + (4 * 2 + 1) * 4;
    patch<float>(b, at2, std::numeric_limits<float>::infinity());
    EXPECT_THAT(read_error(b), HasSubstr(fmt::format("byte {}: SxV matrix of channel 0 holds Inf "
                                                     "at row 4, column 1",
                                                     at2)));
}

TEST_F(Ubo2014MalformedTest, UnknownColourModel) {
    std::vector<uint8_t> b = m_bytes;
    patch<int32_t>(b, m_layout.body + 4, 3);
    EXPECT_THAT(read_error(b), HasSubstr(fmt::format("byte {}: unsupported DFMF colour model 3",
                                                     m_layout.body + 4)));
}

TEST_F(Ubo2014MalformedTest, InconsistentMetaSize) {
    std::vector<uint8_t> b = m_bytes;
    patch<uint32_t>(b, 9, uint32_t(m_layout.meta_size + 4));
    EXPECT_THAT(read_error(b), HasSubstr(fmt::format("byte 9: meta block declares {} bytes but its "
                                                     "version 4 fields take {}",
                                                     m_layout.meta_size + 4, m_layout.meta_size)));
    patch<uint32_t>(b, 9, uint32_t(m_layout.meta_size - 1));
    EXPECT_THAT(read_error(b), HasSubstr("name of channel 2 (1 bytes) reaches beyond them"));
    patch<uint32_t>(b, 9, 100u);
    EXPECT_THAT(read_error(b), HasSubstr("fewer than the 264 of its fixed fields"));
    b = m_bytes;
    patch<uint32_t>(b, 13, 0u);
    EXPECT_THAT(read_error(b), HasSubstr("meta block version 0"));
}

TEST_F(Ubo2014MalformedTest, ViewsWithDifferentLightSets) {
    std::vector<uint8_t> b = m_bytes;
    const size_t view1 = m_layout.dirs + 4 + 12 + 24;
    patch<float>(b, view1 + 12 + 2 * 8, 0.7f);  // θ of light 2 of view 1
    EXPECT_THAT(read_error(b), HasSubstr("view 1 carries a different light set than view 0 "
                                         "(light 2"));
    b = m_bytes;
    patch<uint32_t>(b, view1 + 8, 2u);
    EXPECT_THAT(read_error(b), HasSubstr("view 1 declares 2 lights but view 0 declared 3"));
    b = m_bytes;
    patch<float>(b, view1, 2.5f);  // θ of view 1 below the horizon
    EXPECT_THAT(read_error(b), HasSubstr("view 1 has direction θ = 2.5 rad"));
}

}  // namespace
}  // namespace btf::ubo2014
