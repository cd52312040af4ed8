// SPDX-License-Identifier: MIT
#include "btf/core/hemisphere.h"

#include <gtest/gtest.h>

#include <random>

namespace btf {
namespace {

TEST(Hemisphere, ConcentricMapLandmarks) {
    const DiskPoint centre = square_to_disk({0.5, 0.5});
    EXPECT_DOUBLE_EQ(centre.x, 0);
    EXPECT_DOUBLE_EQ(centre.y, 0);
    const DiskPoint right = square_to_disk({1, 0.5});
    EXPECT_NEAR(right.x, 1, 1e-15);
    EXPECT_NEAR(right.y, 0, 1e-15);
    const DiskPoint top = square_to_disk({0.5, 1});
    EXPECT_NEAR(top.x, 0, 1e-15);
    EXPECT_NEAR(top.y, 1, 1e-15);
    // The square's corners land on the diagonals of the disk's rim.
    const DiskPoint corner = square_to_disk({1, 1});
    EXPECT_NEAR(corner.x, std::sqrt(0.5), 1e-15);
    EXPECT_NEAR(corner.y, std::sqrt(0.5), 1e-15);
    // Every point of the square's boundary lands on the rim.
    for (int i = 0; i <= 100; ++i) {
        const double s = i / 100.0;
        for (const SquarePoint p :
             {SquarePoint{s, 0}, SquarePoint{s, 1}, SquarePoint{0, s}, SquarePoint{1, s}}) {
            const DiskPoint d = square_to_disk(p);
            EXPECT_NEAR(std::hypot(d.x, d.y), 1, 1e-14) << p.u << " " << p.v;
        }
    }
}

TEST(Hemisphere, ZenithCentreAndHorizonBoundary) {
    const Vec3 zenith = square_to_hemisphere({0.5, 0.5});
    EXPECT_NEAR(zenith.z, 1, 1e-15);
    const SquarePoint c = hemisphere_to_square({0, 0, 1});
    EXPECT_DOUBLE_EQ(c.u, 0.5);
    EXPECT_DOUBLE_EQ(c.v, 0.5);
    // +x on the horizon is the middle of the right edge, +y the middle of the top edge.
    const SquarePoint px = hemisphere_to_square({1, 0, 0});
    EXPECT_NEAR(px.u, 1, 1e-15);
    EXPECT_NEAR(px.v, 0.5, 1e-15);
    const SquarePoint py = hemisphere_to_square({0, 1, 0});
    EXPECT_NEAR(py.u, 0.5, 1e-15);
    EXPECT_NEAR(py.v, 1, 1e-15);
    for (int i = 0; i <= 64; ++i) {
        const Vec3 h = square_to_hemisphere({i / 64.0, 0});
        EXPECT_NEAR(h.z, 0, 1e-15);
        EXPECT_NEAR(length(h), 1, 1e-15);
    }
}

TEST(Hemisphere, ForwardGivesUnitVectorsWithLambertHeight) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> uni(0, 1);
    for (int i = 0; i < 10000; ++i) {
        const SquarePoint p{uni(rng), uni(rng)};
        const DiskPoint disk = square_to_disk(p);
        const Vec3 d = square_to_hemisphere(p);
        EXPECT_NEAR(length(d), 1, 1e-14);
        EXPECT_GE(d.z, 0);
        EXPECT_NEAR(d.z, 1 - (disk.x * disk.x + disk.y * disk.y), 1e-14);
        // The azimuth is kept from the disk to the hemisphere.
        EXPECT_NEAR(d.x * disk.y - d.y * disk.x, 0, 1e-14);
    }
}

TEST(Hemisphere, RoundTrips) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uni(0, 1);
    for (int i = 0; i < 100000; ++i) {
        const SquarePoint p{uni(rng), uni(rng)};
        const SquarePoint q = hemisphere_to_square(square_to_hemisphere(p));
        ASSERT_NEAR(q.u, p.u, 1e-12) << p.u << " " << p.v;
        ASSERT_NEAR(q.v, p.v, 1e-12) << p.u << " " << p.v;
    }
    for (int i = 0; i < 100000; ++i) {
        // Uniform directions on the hemisphere.
        const double z = uni(rng), phi = 2 * kPi * uni(rng);
        const double s = std::sqrt(1 - z * z);
        const Vec3 d{s * std::cos(phi), s * std::sin(phi), z};
        const Vec3 e = square_to_hemisphere(hemisphere_to_square(d));
        ASSERT_NEAR(length(e - d), 0, 1e-12) << z << " " << phi;
    }
}

TEST(Hemisphere, InverseAcceptsAnyLengthAndClampsBelowHorizon) {
    const Vec3 d = normalize(Vec3{0.3, -0.5, 0.7});
    const SquarePoint a = hemisphere_to_square(d);
    const SquarePoint b = hemisphere_to_square(d * 123.0);
    const SquarePoint c = hemisphere_to_square(d * 1e-150);
    EXPECT_NEAR(a.u, b.u, 1e-15);
    EXPECT_NEAR(a.v, b.v, 1e-15);
    EXPECT_NEAR(a.u, c.u, 1e-15);
    EXPECT_NEAR(a.v, c.v, 1e-15);
    // Below the horizon: the horizon point at the same azimuth.
    const SquarePoint below = hemisphere_to_square({0.3, -0.5, -0.7});
    const SquarePoint horizon = hemisphere_to_square({0.3, -0.5, 0});
    EXPECT_DOUBLE_EQ(below.u, horizon.u);
    EXPECT_DOUBLE_EQ(below.v, horizon.v);
    // No direction at all: +x on the horizon.
    for (const Vec3 v : {Vec3{0, 0, 0}, Vec3{0, 0, -1}, Vec3{NAN, 0, 1}}) {
        const SquarePoint p = hemisphere_to_square(v);
        EXPECT_DOUBLE_EQ(p.u, 1);
        EXPECT_DOUBLE_EQ(p.v, 0.5);
    }
}

TEST(Hemisphere, GridCellsHaveEqualSolidAngle) {
    // Each cell of an R × R grid over the square must cover 2π / R² steradians. The cell's
    // image is measured by splitting it into k × k small quads, each as two spherical triangles.
    constexpr int kR = 16, kSub = 12;
    const double expected = 2 * kPi / (kR * kR);
    double total = 0, worst = 0;
    for (int j = 0; j < kR; ++j)
        for (int i = 0; i < kR; ++i) {
            double area = 0;
            for (int b = 0; b < kSub; ++b)
                for (int a = 0; a < kSub; ++a) {
                    auto at = [&](int da, int db) {
                        return square_to_hemisphere({(i + (a + da) / double(kSub)) / kR,
                                                     (j + (b + db) / double(kSub)) / kR});
                    };
                    const Vec3 p00 = at(0, 0), p10 = at(1, 0), p01 = at(0, 1), p11 = at(1, 1);
                    area += spherical_triangle_area(p00, p10, p11) +
                            spherical_triangle_area(p00, p11, p01);
                }
            total += area;
            worst = std::max(worst, std::abs(area / expected - 1));
        }
    EXPECT_NEAR(total, 2 * kPi, 1e-6);
    EXPECT_LT(worst, 1e-3) << "largest relative deviation of a cell's solid angle";
}

TEST(Hemisphere, SphericalTriangleArea) {
    // One octant of the sphere: π/2, positive counter-clockwise seen from outside.
    EXPECT_NEAR(spherical_triangle_area({1, 0, 0}, {0, 1, 0}, {0, 0, 1}), kPi / 2, 1e-15);
    EXPECT_NEAR(spherical_triangle_area({1, 0, 0}, {0, 0, 1}, {0, 1, 0}), -kPi / 2, 1e-15);
    // A small triangle: area ≈ planar area.
    const double e = 1e-3;
    const double small =
        spherical_triangle_area({0, 0, 1}, normalize({e, 0, 1}), normalize({0, e, 1}));
    EXPECT_NEAR(small, e * e / 2, 1e-9);
}

}  // namespace
}  // namespace btf
