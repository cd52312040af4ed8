#include "btf/core/image.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <iterator>

#include "btf/core/color.h"
#include "btf/util/error.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

class ImageTest : public testing::Test {
  protected:
    void SetUp() override {
        m_dir = fs::path(testing::TempDir()) / ("btf_image_test_" + std::to_string(::getpid()));
        fs::remove_all(m_dir);
        fs::create_directories(m_dir);
    }
    void TearDown() override { fs::remove_all(m_dir); }
    fs::path m_dir;
};

Image gradient(int w, int h) {
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            img.set_rgb(x, y, {float(x) / (w - 1), float(y) / (h - 1), 0.25f});
    return img;
}

TEST_F(ImageTest, PngIsSrgbEncodedAndDecodedBack) {
    const Image img = gradient(16, 8);
    write_image(m_dir / "g.png", img);
    const Image linear = read_image(m_dir / "g.png");
    ASSERT_EQ(linear.width(), 16);
    ASSERT_EQ(linear.height(), 8);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 16; ++x)
            for (int c = 0; c < 3; ++c) {
                // 8-bit quantization in sRGB space: half a code step, mapped to linear.
                const float v = img.at(x, y, c);
                const float tol = 0.5f / 255 * std::max(0.1f, 2.4f * std::pow(v, 1 / 1.7f)) + 1e-4f;
                EXPECT_NEAR(linear.at(x, y, c), v, tol) << x << "," << y << "," << c;
            }
    // Raw keeps the code values: 0.25 linear → sRGB 0.537.
    const Image raw = read_image(m_dir / "g.png", Encoding::kRaw);
    EXPECT_NEAR(raw.at(0, 0, 2), linear_to_srgb(0.25f), 1.0f / 255);
}

TEST_F(ImageTest, ExrKeepsLinearHalfValues) {
    Image img = gradient(8, 8);
    img.at(3, 3, 0) = 7.5f;  // HDR value survives
    write_image(m_dir / "g.exr", img);
    const Image back = read_image(m_dir / "g.exr");
    for (size_t i = 0; i < img.values().size(); ++i)
        EXPECT_NEAR(back.values()[i], img.values()[i], 2e-3 * std::max(1.0f, img.values()[i]));
}

TEST_F(ImageTest, DecodesFromMemory) {
    write_image(m_dir / "g.jpg", gradient(32, 32));
    std::ifstream in(m_dir / "g.jpg", std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
    const Image img = read_image_memory(bytes.data(), bytes.size(), "mem.jpg");
    EXPECT_EQ(img.width(), 32);
    // JPEG is lossy (and subsamples chroma): compare the mean of each channel.
    const Image ref = gradient(32, 32);
    for (int c = 0; c < 3; ++c) {
        double a = 0, b = 0;
        for (int64_t p = 0; p < img.num_pixels(); ++p)
            a += img.data()[p * 3 + c], b += ref.data()[p * 3 + c];
        EXPECT_NEAR(a / img.num_pixels(), b / img.num_pixels(), 0.02) << c;
    }
    EXPECT_THROW(read_image_memory(bytes.data(), bytes.size() / 3, "cut.jpg"), Error);
}

TEST_F(ImageTest, ErrorsNameTheFile) {
    std::ofstream(m_dir / "junk.png") << "this is not a png";
    try {
        read_image(m_dir / "junk.png");
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("junk.png"), std::string::npos) << e.what();
    }
    EXPECT_THROW(read_image(m_dir / "missing.png"), Error);
    EXPECT_THROW(write_image(m_dir / "x.unknownext", gradient(2, 2)), Error);
    EXPECT_FALSE(fs::exists(m_dir / "x.unknownext"));
}

TEST(Image, BilinearIsExactAtTexelCentres) {
    const Image img = gradient(4, 4);
    const Rgb c = img.bilinear(2.5, 1.5);
    EXPECT_FLOAT_EQ(c.r, img.at(2, 1, 0));
    const Rgb mid = img.bilinear(2.0, 1.5);
    EXPECT_FLOAT_EQ(mid.r, 0.5f * (img.at(1, 1, 0) + img.at(2, 1, 0)));
}

}  // namespace
}  // namespace btf
