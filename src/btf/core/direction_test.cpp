// SPDX-License-Identifier: MIT
#include "btf/core/direction.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <map>

#include "btf/util/error.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

TEST(Direction, VectorConventions) {
    // z = normal, x = tangent (φ = 0), φ from +x toward +y.
    const Vec3 zenith = Direction{0, 0}.vector();
    EXPECT_NEAR(zenith.z, 1.0, 1e-12);
    const Vec3 x = Direction::from_degrees(90, 0).vector();
    EXPECT_NEAR(x.x, 1.0, 1e-12);
    const Vec3 y = Direction::from_degrees(90, 90).vector();
    EXPECT_NEAR(y.y, 1.0, 1e-12);
    const Direction d = Direction::from_vector({-1, -1, std::sqrt(2.0)});
    EXPECT_NEAR(d.theta_deg(), 45.0, 1e-9);
    EXPECT_NEAR(d.phi_deg(), 225.0, 1e-9);
    EXPECT_NEAR(Direction::from_degrees(30, -30).phi_deg(), 330.0, 1e-9);
}

TEST(DirectionSet, Ubo81RingsAndOrder) {
    const DirectionSet& s = DirectionSet::ubo81();
    ASSERT_EQ(s.size(), 81);
    std::map<int, int> rings;
    for (const Direction& d : s.directions()) rings[int(std::lround(d.theta_deg()))]++;
    EXPECT_EQ(rings, (std::map<int, int>{{0, 1}, {15, 6}, {30, 12}, {45, 18}, {60, 20}, {75, 24}}));
    // Index order of the database: FORMATS.md example "00008 tl000 pl000 tv030 pv030" is view
    // index 8 = θ 30°, φ 30° (1 + 6 + 1).
    EXPECT_NEAR(s[8].theta_deg(), 30.0, 1e-9);
    EXPECT_NEAR(s[8].phi_deg(), 30.0, 1e-9);
    EXPECT_NEAR(s[80].theta_deg(), 75.0, 1e-9);
    EXPECT_NEAR(s[80].phi_deg(), 345.0, 1e-9);
    EXPECT_EQ(s.find(Direction::from_degrees(60, 342)), 1 + 6 + 12 + 18 + 19);
    EXPECT_EQ(s.find(Direction::from_degrees(60, 343)), -1);
}

TEST(DirectionSet, Dome151RingsAndOffsets) {
    const DirectionSet& s = DirectionSet::dome151();
    ASSERT_EQ(s.size(), 151);
    EXPECT_NEAR(s[1].theta_deg(), 11.0, 1e-9);
    EXPECT_NEAR(s[1].phi_deg(), 15.0, 1e-9);
    // Ring 52.5° starts at index 1+6+12+12+12+18 = 61 with φ offset 7.5°.
    EXPECT_NEAR(s[61].theta_deg(), 52.5, 1e-9);
    EXPECT_NEAR(s[61].phi_deg(), 7.5, 1e-9);
    EXPECT_NEAR(s[150].theta_deg(), 75.0, 1e-9);
    EXPECT_NEAR(s[150].phi_deg(), 345.0, 1e-9);
}

TEST(DirectionSet, FileRoundTripAndErrors) {
    const fs::path dir =
        fs::path(testing::TempDir()) / ("btf_direction_test_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path file = dir / "dirs.txt";
    DirectionSet::dome151().write(file);
    const DirectionSet back = DirectionSet::read(file);
    EXPECT_TRUE(back.same_directions(DirectionSet::dome151()));
    EXPECT_EQ(DirectionSet::named("ubo81").size(), 81);

    auto expect_error = [&](const std::string& text, const std::string& message) {
        { std::ofstream(dir / "bad.txt") << text; }
        try {
            DirectionSet::read(dir / "bad.txt");
            FAIL() << "no error for " << text;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("bad.txt"), std::string::npos) << e.what();
        }
    };
    expect_error("0 0\n12 abc\n", "line 2: 'abc' is not a number");
    expect_error("# only a comment\n", "no directions");
    expect_error("95 10\n", "line 1: theta 95 is outside [0, 90]");
    expect_error("10 20 30\n", "line 1: expected two numbers");
    EXPECT_THROW(DirectionSet::read(dir / "missing.txt"), Error);
    fs::remove_all(dir);
}

TEST(DirectionSet, SubsetAndNearest) {
    const DirectionSet& s = DirectionSet::ubo81();
    const DirectionSet sub = s.subset({0, 7, 19}, "three");
    ASSERT_EQ(sub.size(), 3);
    EXPECT_TRUE(sub[1].theta_deg() == s[7].theta_deg());
    EXPECT_EQ(s.nearest(Direction::from_degrees(14, 2).vector()), 1);
}

}  // namespace
}  // namespace btf
