// SPDX-License-Identifier: MIT
#include "btf/io/image_set.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <zip.h>

#include <fstream>

#include "btf/util/error.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

TEST(AngleNames, ParsesWholeAndDecimalDegrees) {
    EXPECT_EQ(parse_angle_degrees("075"), 75.0);
    EXPECT_EQ(parse_angle_degrees("0"), 0.0);
    EXPECT_EQ(parse_angle_degrees("023.5"), 23.5);
    EXPECT_EQ(parse_angle_degrees("007.25"), 7.25);
    for (const char* bad : {"", "-15", "+15", "1e2", "15.", ".5", "1.2.3", "x15", "15 "})
        EXPECT_FALSE(parse_angle_degrees(bad)) << bad;
}

TEST(AngleNames, FormatsThreeDigitsOrDecimals) {
    EXPECT_EQ(format_angle_degrees(0), "000");
    EXPECT_EQ(format_angle_degrees(75), "075");
    EXPECT_EQ(format_angle_degrees(degrees(radians(345))), "345");  // radian round trip noise
    EXPECT_EQ(format_angle_degrees(23.5), "023.5");
    EXPECT_EQ(format_angle_degrees(7.25), "007.25");
    EXPECT_EQ(format_angle_degrees(1.0 / 3), "000.333");
    for (double a : {0.0, 11.0, 23.5, 7.25, 345.0, 52.125})
        EXPECT_DOUBLE_EQ(*parse_angle_degrees(format_angle_degrees(a)), a);
}

TEST(AngleNames, ParsesFourFields) {
    auto f = parse_angle_fields("tl015_pl060_tv030_pv330", '_');
    ASSERT_TRUE(f);
    EXPECT_EQ(f->light_theta, 15);
    EXPECT_EQ(f->light_phi, 60);
    EXPECT_EQ(f->view_theta, 30);
    EXPECT_EQ(f->view_phi, 330);
    EXPECT_TRUE(parse_angle_fields("tl015 pl060 tv030 pv330", ' '));
    // φ is folded to 0 at the zenith.
    EXPECT_EQ(parse_angle_fields("tl000_pl090_tv000_pv000", '_')->light_phi, 0);
    for (const char* bad :
         {"tl015_pl060_tv030", "tl015_pl060_tv030_pv330_", "pl015_tl060_tv030_pv330",
          "tl091_pl000_tv000_pv000", "tl015_pl360_tv000_pv000", "tl015__pl060_tv030_pv330",
          "tl015 pl060_tv030_pv330"})
        EXPECT_FALSE(parse_angle_fields(bad, '_')) << bad;
    EXPECT_EQ(format_direction_fields(Direction::from_degrees(0, 250), "tl", "pl", ' '),
              "tl000 pl000");
    EXPECT_EQ(format_direction_fields(Direction::from_degrees(67.5, 7.5), "tv", "pv", '_'),
              "tv067.5_pv007.5");
}

TEST(DirectionSetFrom, RecognizesBuiltInSetsInAnyOrder) {
    std::vector<Direction> dirs = DirectionSet::ubo81().directions();
    std::reverse(dirs.begin(), dirs.end());
    EXPECT_EQ(direction_set_from(dirs, "x").name(), "ubo81");
    dirs = DirectionSet::dome151().directions();
    std::rotate(dirs.begin(), dirs.begin() + 40, dirs.end());
    const DirectionSet dome = direction_set_from(dirs, "x");
    EXPECT_EQ(dome.name(), "dome151");
    EXPECT_TRUE(dome.same_directions(DirectionSet::dome151()));
    dirs.pop_back();
    const DirectionSet other = direction_set_from(dirs, "mine");
    EXPECT_EQ(other.name(), "mine");
    EXPECT_EQ(other.size(), 150);
    for (int i = 1; i < other.size(); ++i) {
        const bool ordered = other[i - 1].theta_deg() < other[i].theta_deg() - 1e-9 ||
                             (std::abs(other[i - 1].theta_deg() - other[i].theta_deg()) < 1e-9 &&
                              other[i - 1].phi_deg() < other[i].phi_deg());
        EXPECT_TRUE(ordered) << i;
    }
}

class ImageFilesTest : public testing::Test {
  protected:
    void SetUp() override {
        m_dir = fs::path(testing::TempDir()) /
                fmt::format("btf_image_set_test_{}_{}", ::getpid(),
                            testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(m_dir);
        fs::create_directories(m_dir / "tree/a/b/c");
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(m_dir, ec);
    }
    fs::path m_dir;
};

TEST_F(ImageFilesTest, FolderDepthHiddenFilesAndHeaders) {
    write_image(m_dir / "tree/top.png", Image(5, 3, 3, 0.25f));
    write_image(m_dir / "tree/a/one.png", Image(2, 2, 3, 0.5f));
    write_image(m_dir / "tree/a/b/c/deep.png", Image(2, 2, 3, 0.5f));
    std::ofstream(m_dir / "tree/.hidden") << "x";
    auto files = ImageFiles::folder(m_dir / "tree", 2);
    EXPECT_FALSE(files->is_archive());
    ASSERT_EQ(files->size(), 2);  // deep.png is 4 levels down, .hidden is hidden
    EXPECT_EQ(files->name(0), "a/one.png");
    EXPECT_EQ(files->name(1), "top.png");
    EXPECT_EQ(files->label(1), (m_dir / "tree" / "top.png").string());
    EXPECT_EQ(files->image_size(1), (std::pair<int, int>{5, 3}));
    EXPECT_EQ(files->read(1, 8).size(), 8u);
    EXPECT_EQ(files->decode(1, Encoding::kRaw).width(), 5);
}

TEST_F(ImageFilesTest, ZipEntriesAndChecks) {
    write_image(m_dir / "img.png", Image(4, 6, 3, 0.25f));
    const fs::path archive = m_dir / "a.zip";
    int error = 0;
    zip_t* za = zip_open(archive.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
    ASSERT_NE(za, nullptr);
    zip_dir_add(za, "folder", 0);
    zip_file_add(za, "folder/img.png", zip_source_file(za, (m_dir / "img.png").c_str(), 0, -1), 0);
    zip_file_add(za, "junk.png", zip_source_buffer(za, "not an image", 12, 0), 0);
    ASSERT_EQ(zip_close(za), 0);

    auto files = ImageFiles::zip(archive);
    EXPECT_TRUE(files->is_archive());
    ASSERT_EQ(files->size(), 2);  // the folder entry is not a file
    EXPECT_EQ(files->name(0), "folder/img.png");
    EXPECT_EQ(files->label(0), archive.string() + ": folder/img.png");
    EXPECT_EQ(files->file_size(0), fs::file_size(m_dir / "img.png"));
    EXPECT_EQ(files->image_size(0), (std::pair<int, int>{4, 6}));
    EXPECT_EQ(files->read(0).size(), files->file_size(0));
    const Image image = files->decode(0, Encoding::kLinear);
    EXPECT_EQ(image.height(), 6);
    EXPECT_NEAR(image.at(1, 1, 0), 0.25f, 3e-3);
    try {
        files->image_size(1);
        ADD_FAILURE() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(std::string(e.what()),
                    AllOf(HasSubstr("a.zip: junk.png"), HasSubstr("not a readable image")));
    }
    try {
        ImageFiles::zip(m_dir / "img.png");
        ADD_FAILURE() << "expected an error";
    } catch (const Error& e) {
        EXPECT_THAT(std::string(e.what()),
                    AllOf(HasSubstr("img.png"), HasSubstr("not a readable zip archive")));
    }
}

}  // namespace
}  // namespace btf
