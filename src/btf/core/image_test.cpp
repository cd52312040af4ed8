// SPDX-License-Identifier: MIT
#include "btf/core/image.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <functional>
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

// A DDS volume texture of 4 × 4 texels and `depth` slices, uncompressed 32-bit BGRA.
std::vector<uint8_t> dds_volume(uint32_t depth) {
    std::vector<uint8_t> bytes(4 + 124);
    auto put = [&](size_t offset, uint32_t v) {
        for (int i = 0; i < 4; ++i) bytes[offset + i] = uint8_t(v >> (8 * i));
    };
    std::memcpy(bytes.data(), "DDS ", 4);
    const size_t h = 4;  // the header follows the magic
    put(h + 0, 124);
    put(h + 4, 0x1 | 0x2 | 0x4 | 0x1000 | 0x800000);  // caps, height, width, pixel format, depth
    put(h + 8, 4), put(h + 12, 4), put(h + 16, 16), put(h + 20, depth);
    put(h + 72, 32), put(h + 76, 0x40 | 0x1);  // pixel format: RGB with alpha
    put(h + 84, 32), put(h + 88, 0x00ff0000), put(h + 92, 0x0000ff00), put(h + 96, 0x000000ff);
    put(h + 100, 0xff000000);
    put(h + 104, 0x1000 | 0x8), put(h + 108, 0x200000);  // texture, complex; volume
    bytes.resize(bytes.size() + size_t(4 * 4 * 4) * depth, 0x80);
    return bytes;
}

TEST_F(ImageTest, VolumeImagesAreRefusedNotDecodedIntoOneSlice) {
    // The decoder would write every slice into a buffer sized for one.
    const std::vector<uint8_t> volume = dds_volume(64);
    std::ofstream(m_dir / "volume.dds", std::ios::binary)
        .write(reinterpret_cast<const char*>(volume.data()), std::streamsize(volume.size()));
    for (const auto& read : std::vector<std::function<void()>>{
             [&] { read_image(m_dir / "volume.dds"); },
             [&] { read_image_memory(volume.data(), volume.size(), "volume.dds"); },
             [&] { read_image_size_memory(volume.data(), volume.size(), "volume.dds"); }}) {
        try {
            read();
            ADD_FAILURE() << "a volume was read";
        } catch (const Error& e) {
            EXPECT_THAT(e.what(), testing::HasSubstr("volume.dds: image is a volume of 64 slices"));
        }
    }
    // One slice is an ordinary image.
    const std::vector<uint8_t> flat = dds_volume(1);
    const Image image = read_image_memory(flat.data(), flat.size(), "flat.dds", Encoding::kRaw);
    ASSERT_EQ(image.width(), 4);
    EXPECT_NEAR(image.at(3, 3, 0), 128 / 255.0, 1e-6);
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
