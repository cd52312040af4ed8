// SPDX-License-Identifier: MIT
#include "btf/render/mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <string>

#include "btf/testing/support.h"

namespace btf::render {
namespace {

Vec3 vec(const std::vector<float>& data, size_t i) {
    return {data[3 * i], data[3 * i + 1], data[3 * i + 2]};
}
Vec3 position(const TriangleMesh& m, size_t i) {
    return vec(m.positions, i);
}
Vec3 normal(const TriangleMesh& m, size_t i) {
    return vec(m.normals, i);
}
Vec3 tangent(const TriangleMesh& m, size_t i) {
    return vec(m.tangents, i);
}
double u_of(const TriangleMesh& m, size_t i) {
    return m.uvs[2 * i];
}
double v_of(const TriangleMesh& m, size_t i) {
    return m.uvs[2 * i + 1];
}

double total_area(const TriangleMesh& m) {
    double area = 0;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
        const Vec3 p0 = position(m, m.indices[3 * t]);
        area += 0.5 * length(cross(position(m, m.indices[3 * t + 1]) - p0,
                                   position(m, m.indices[3 * t + 2]) - p0));
    }
    return area;
}

struct Expectations {
    // Point inside the surface that the normal at p must point away from; null skips the test.
    std::function<Vec3(const Vec3&)> centre = nullptr;
    // Minimum cosine between a vertex tangent and its triangles' finite-difference dP/du.
    double tangent_cos = 0.999;
    // Analytic surface area; <= 0 skips the test.
    double area = 0;
    double area_tolerance = 0.01;
    // uv must lie in [0, 1].
    bool unit_uvs = true;
    // Largest u and v extents of a triangle; a triangle wrapping across a seam spans almost 1.
    double max_u_span = 1.0;
    double max_v_span = 1.0;
};

// Every property of the header's conventions, on every vertex and triangle. Stops at the first
// violation (use with ASSERT_NO_FATAL_FAILURE) so that a broken shape gives one message.
void check_mesh(const TriangleMesh& m, const Expectations& expect) {
    const size_t n = m.vertex_count();
    ASSERT_GT(n, 0u);
    ASSERT_EQ(m.positions.size(), 3 * n);
    ASSERT_EQ(m.normals.size(), 3 * n);
    ASSERT_EQ(m.tangents.size(), 3 * n);
    ASSERT_EQ(m.uvs.size(), 2 * n);
    ASSERT_EQ(m.indices.size() % 3, 0u);
    ASSERT_GT(m.triangle_count(), 0u);

    for (size_t i = 0; i < n; ++i) {
        const Vec3 p = position(m, i), nn = normal(m, i), t = tangent(m, i);
        ASSERT_NEAR(length(nn), 1.0, 1e-5) << "vertex " << i;
        ASSERT_NEAR(length(t), 1.0, 1e-5) << "vertex " << i;
        ASSERT_NEAR(dot(nn, t), 0.0, 1e-5) << "vertex " << i;
        if (expect.centre) {
            ASSERT_GT(dot(nn, p - expect.centre(p)), 0.0) << "vertex " << i << " normal inward";
        }
        if (expect.unit_uvs) {
            ASSERT_GE(u_of(m, i), 0.0);
            ASSERT_LE(u_of(m, i), 1.0);
            ASSERT_GE(v_of(m, i), 0.0);
            ASSERT_LE(v_of(m, i), 1.0);
        }
    }

    for (size_t t = 0; t < m.triangle_count(); ++t) {
        const uint32_t c[3] = {m.indices[3 * t], m.indices[3 * t + 1], m.indices[3 * t + 2]};
        for (uint32_t k : c) ASSERT_LT(k, n) << "triangle " << t;
        const Vec3 p0 = position(m, c[0]);
        const Vec3 e1 = position(m, c[1]) - p0, e2 = position(m, c[2]) - p0;
        const Vec3 geometric = cross(e1, e2);
        ASSERT_GT(length(geometric), 0.0) << "triangle " << t << " is degenerate";
        const double du1 = u_of(m, c[1]) - u_of(m, c[0]), dv1 = v_of(m, c[1]) - v_of(m, c[0]);
        const double du2 = u_of(m, c[2]) - u_of(m, c[0]), dv2 = v_of(m, c[2]) - v_of(m, c[0]);
        ASSERT_LE(std::max({std::abs(du1), std::abs(du2), std::abs(du1 - du2)}), expect.max_u_span)
            << "triangle " << t << " wraps across the u seam";
        ASSERT_LE(std::max({std::abs(dv1), std::abs(dv2), std::abs(dv1 - dv2)}), expect.max_v_span)
            << "triangle " << t << " wraps across the v seam";
        const double det = du1 * dv2 - du2 * dv1;
        ASSERT_NE(det, 0.0) << "triangle " << t << " has degenerate uvs";
        const Vec3 dpdu = (e1 * dv2 - e2 * dv1) / det;
        const Vec3 dpdv = (e2 * du1 - e1 * du2) / det;
        for (uint32_t k : c) {
            const Vec3 nn = normal(m, k), tt = tangent(m, k);
            ASSERT_GT(dot(geometric, nn), 0.0) << "triangle " << t << ": winding against normal";
            ASSERT_GT(dot(normalize(dpdu), tt), expect.tangent_cos)
                << "triangle " << t << ", vertex " << k << ": tangent is not dP/du";
            ASSERT_GT(dot(dpdv, cross(nn, tt)), 0.0)
                << "triangle " << t << ", vertex " << k << ": mirrored uv orientation";
        }
    }

    if (expect.area > 0) {
        EXPECT_NEAR(total_area(m), expect.area, expect.area_tolerance * expect.area);
    }
}

Vec3 origin(const Vec3&) {
    return {};
}

// The point of a torus' tube centre line nearest to p.
std::function<Vec3(const Vec3&)> tube_centre_of(double major_radius) {
    return [major_radius](const Vec3& p) { return normalize(Vec3{p.x, 0, p.z}) * major_radius; };
}

// Vertex angle step π/segments separates a vertex tangent from the chord direction of its
// triangles' dP/du; allow that plus float rounding.
double chord_cos(int segments) {
    return std::cos(kPi / segments) - 1e-4;
}

// ---- generators ------------------------------------------------------------------------------

TEST(Mesh, PlaneFollowsTheConventions) {
    const TriangleMesh m = make_plane(3.0, 2.0);
    EXPECT_EQ(m.vertex_count(), 4u);
    EXPECT_EQ(m.triangle_count(), 2u);
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.centre =
                                               [](const Vec3& p) {
                                                   return p - Vec3{0, 1, 0};
                                               },
                                           .area = 6.0}));
    EXPECT_NEAR(total_area(m), 6.0, 1e-6);
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        EXPECT_EQ(normal(m, i), (Vec3{0, 1, 0}));
        EXPECT_EQ(tangent(m, i), (Vec3{1, 0, 0}));
        // u along +x, v towards -z, covering the rectangle once.
        EXPECT_NEAR(position(m, i).x, -1.5 + 3.0 * u_of(m, i), 1e-6);
        EXPECT_NEAR(position(m, i).z, 1.0 - 2.0 * v_of(m, i), 1e-6);
        EXPECT_EQ(position(m, i).y, 0.0f);
    }
}

TEST(Mesh, SphereFollowsTheConventions) {
    const double r = 1.5;
    const TriangleMesh m = make_sphere(r, 64);
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.centre = origin,
                                           .tangent_cos = chord_cos(64),
                                           .area = 4 * kPi * r * r,
                                           .max_u_span = 0.5}));
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        const Vec3 p = position(m, i);
        EXPECT_NEAR(length(p), r, 1e-5);
        // v from the south pole to the north pole.
        EXPECT_NEAR(p.y, -r * std::cos(kPi * v_of(m, i)), 1e-5);
    }
    // Coarse and odd segment counts keep every convention (the area needs finer meshes).
    for (int segments : {4, 5, 7, 12}) {
        SCOPED_TRACE(segments);
        ASSERT_NO_FATAL_FAILURE(check_mesh(
            make_sphere(r, segments),
            {.centre = origin, .tangent_cos = chord_cos(segments) - 1e-3, .max_u_span = 0.5}));
    }
}

TEST(Mesh, SpherePolesHaveOneVertexPerSegment) {
    const TriangleMesh m = make_sphere(1.0, 16);
    size_t south = 0, north = 0;
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        if (v_of(m, i) == 0.0) {
            ++south;
            EXPECT_EQ(normal(m, i), (Vec3{0, -1, 0}));
        }
        if (v_of(m, i) == 1.0) {
            ++north;
            EXPECT_EQ(normal(m, i), (Vec3{0, 1, 0}));
        }
        EXPECT_TRUE(std::isfinite(length(tangent(m, i))));
    }
    EXPECT_EQ(south, 16u);
    EXPECT_EQ(north, 16u);
}

TEST(Mesh, CylinderFollowsTheConventions) {
    const double r = 0.5, h = 2.0;
    const TriangleMesh m = make_cylinder(r, h, 64);
    auto axis_point = [](const Vec3& p) { return Vec3{0, p.y, 0}; };
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.centre = axis_point,
                                           .tangent_cos = chord_cos(64),
                                           .area = 2 * kPi * r * h,
                                           .max_u_span = 0.5}));
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        const Vec3 p = position(m, i);
        EXPECT_NEAR(std::hypot(p.x, p.z), r, 1e-6);
        EXPECT_NEAR(p.y, (v_of(m, i) - 0.5) * h, 1e-6);  // v from bottom to top
        EXPECT_NEAR(normal(m, i).y, 0.0, 1e-7);          // open side, no caps
    }
    ASSERT_NO_FATAL_FAILURE(
        check_mesh(make_cylinder(1.0, 0.01, 3),
                   {.centre = axis_point, .tangent_cos = 0.49, .max_u_span = 0.5}));
}

TEST(Mesh, TorusFollowsTheConventions) {
    const double major = 2.0, minor = 0.5;
    const TriangleMesh m = make_torus(major, minor, 96, 48);
    const auto tube_centre = tube_centre_of(major);
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.centre = tube_centre,
                                           .tangent_cos = chord_cos(96),
                                           .area = 4 * kPi * kPi * major * minor,
                                           .max_u_span = 0.5,
                                           .max_v_span = 0.5}));
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        const Vec3 p = position(m, i);
        EXPECT_NEAR(length(p - tube_centre(p)), minor, 1e-5);
        if (u_of(m, i) == 0.0 && v_of(m, i) == 0.0) {  // seam corner on the inner equator
            EXPECT_NEAR(p.x, major - minor, 1e-6);
            EXPECT_NEAR(p.y, 0.0, 1e-6);
        }
    }
    ASSERT_NO_FATAL_FAILURE(check_mesh(make_torus(1.0, 0.9, 6, 4), {.centre = tube_centre_of(1.0),
                                                                    .tangent_cos = 0.86,
                                                                    .max_u_span = 0.5,
                                                                    .max_v_span = 0.5}));
}

TEST(Mesh, SeamVerticesShareTheirPositions) {
    // The u = 0 and u = 1 copies of a seam vertex must coincide bit for bit (watertight).
    const TriangleMesh m = make_torus(2.0, 0.5, 10, 6);
    size_t seam = 0;
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        if (u_of(m, i) != 1.0) continue;
        for (size_t j = 0; j < m.vertex_count(); ++j) {
            if (u_of(m, j) == 0.0 && v_of(m, j) == v_of(m, i)) {
                EXPECT_EQ(position(m, i), position(m, j));
                ++seam;
            }
        }
    }
    EXPECT_EQ(seam, 7u);
}

TEST(Mesh, GeneratorsRejectBadArguments) {
    EXPECT_NE(test::error_of([] { make_plane(0, 1); }).find("make_plane"), std::string::npos);
    EXPECT_NE(test::error_of([] { make_sphere(1, 3); }).find("at least 4 segments"),
              std::string::npos);
    EXPECT_NE(test::error_of([] { make_cylinder(-1, 1, 8); }).find("make_cylinder"),
              std::string::npos);
    EXPECT_NE(test::error_of([] { make_torus(1, 2, 8, 8); }).find("minor radius"),
              std::string::npos);
}

// ---- OBJ files -------------------------------------------------------------------------------

class ObjFiles : public ::testing::Test {
  protected:
    std::filesystem::path write(const std::string& name, const std::string& text) {
        const auto path = m_folder.path() / name;
        std::ofstream(path) << text;
        return path;
    }

    test::TempFolder m_folder{"mesh"};
};

TEST_F(ObjFiles, QuadWithTexcoordsAndNormals) {
    // Material statements must not matter: the .mtl does not even exist.
    const auto path = write("quad.obj",
                            "mtllib missing.mtl\n"
                            "o quad\n"
                            "v -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\n"
                            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                            "vn 0 2 0\n"  // not unit: must come out normalized
                            "usemtl cloth\n"
                            "f 1/1/1 2/2/1 3/3/1 4/4/1\n");
    const TriangleMesh m = load_obj(path);
    EXPECT_EQ(m.vertex_count(), 4u);
    EXPECT_EQ(m.triangle_count(), 2u);
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.centre =
                                               [](const Vec3& p) {
                                                   return p - Vec3{0, 1, 0};
                                               },
                                           .area = 4.0}));
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        EXPECT_EQ(normal(m, i), (Vec3{0, 1, 0}));
        EXPECT_NEAR(length(tangent(m, i) - Vec3{1, 0, 0}), 0.0, 1e-6);
    }
}

TEST_F(ObjFiles, TangentFollowsRotatedTexcoords) {
    // u grows towards -z, so dP/du = -z (and v towards -x keeps the orientation unmirrored).
    const auto path = write("rotated.obj",
                            "v -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\n"
                            "vt 0 1\nvt 0 0\nvt 1 0\nvt 1 1\n"
                            "vn 0 1 0\n"
                            "f 1/1/1 2/2/1 3/3/1 4/4/1\n");
    const TriangleMesh m = load_obj(path);
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.area = 4.0}));
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        EXPECT_NEAR(length(tangent(m, i) - Vec3{0, 0, -1}), 0.0, 1e-6);
    }

    // Mirrored uvs (u towards -x, v towards -z) are kept: the tangent is still dP/du, -x.
    const auto mirrored = write("mirrored.obj",
                                "v -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\n"
                                "vt 1 0\nvt 0 0\nvt 0 1\nvt 1 1\n"
                                "vn 0 1 0\n"
                                "f 1/1/1 2/2/1 3/3/1 4/4/1\n");
    const TriangleMesh flipped = load_obj(mirrored);
    for (size_t i = 0; i < flipped.vertex_count(); ++i) {
        EXPECT_NEAR(length(tangent(flipped, i) - Vec3{-1, 0, 0}), 0.0, 1e-6);
    }
}

TEST_F(ObjFiles, MissingNormalsAreAreaWeighted) {
    // A tent of two triangles on a ridge along z: a wide one rising from x = -2 and a narrow one
    // falling to x = 1. The area-weighted ridge normal is exactly +y ((-1, 2, 0) weighted by √5
    // plus (1, 1, 0) weighted by √2); an unweighted average would lean towards +x. Likewise
    // the ridge tangent is exactly +x.
    const auto path = write("tent.obj",
                            "v 0 1 1\nv 0 1 -1\nv -2 0 0\nv 1 0 0\n"
                            "vt 0.5 0\nvt 0.5 1\nvt 0 0.5\nvt 0.75 0.5\n"
                            "f 1/1 2/2 3/3\n"
                            "f 2/2 1/1 4/4\n");
    const TriangleMesh m = load_obj(path);
    EXPECT_EQ(m.vertex_count(), 4u);  // the ridge corners are shared
    EXPECT_EQ(m.triangle_count(), 2u);
    // The ridge tangent (+x) averages the two faces' dP/du, 27° and 45° away from it.
    ASSERT_NO_FATAL_FAILURE(check_mesh(
        m, {.tangent_cos = 0.7, .area = std::sqrt(5.0) + std::sqrt(2.0), .area_tolerance = 1e-6}));
    size_t ridge = 0;
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        const Vec3 p = position(m, i);
        if (p.y == 1.0f) {
            ++ridge;
            EXPECT_NEAR(length(normal(m, i) - Vec3{0, 1, 0}), 0.0, 1e-6);
            EXPECT_NEAR(length(tangent(m, i) - Vec3{1, 0, 0}), 0.0, 1e-6);
        } else if (p.x < 0) {
            EXPECT_NEAR(length(normal(m, i) - normalize(Vec3{-1, 2, 0})), 0.0, 1e-6);
            EXPECT_NEAR(length(tangent(m, i) - normalize(Vec3{2, 1, 0})), 0.0, 1e-6);
        } else {
            EXPECT_NEAR(length(normal(m, i) - normalize(Vec3{1, 1, 0})), 0.0, 1e-6);
            EXPECT_NEAR(length(tangent(m, i) - normalize(Vec3{1, -1, 0})), 0.0, 1e-6);
        }
    }
    EXPECT_EQ(ridge, 2u);
}

TEST_F(ObjFiles, PolygonsAreTriangulatedAndShapesMerged) {
    // A convex hexagon in one object and a concave L-shaped hexagon (area 3) in a group.
    const auto path = write("polygons.obj",
                            "o hexagon\n"
                            "v 1 0 0\nv 0.5 0 -0.866025\nv -0.5 0 -0.866025\nv -1 0 0\n"
                            "v -0.5 0 0.866025\nv 0.5 0 0.866025\n"
                            "vt 1 0.5\nvt 0.75 0.933013\nvt 0.25 0.933013\nvt 0 0.5\n"
                            "vt 0.25 0.066987\nvt 0.75 0.066987\n"
                            "f 1/1 2/2 3/3 4/4 5/5 6/6\n"
                            "g ell\n"
                            "v 3 0 2\nv 5 0 2\nv 5 0 1\nv 4 0 1\nv 4 0 0\nv 3 0 0\n"
                            "vt 0 0\nvt 1 0\nvt 1 0.5\nvt 0.5 0.5\nvt 0.5 1\nvt 0 1\n"
                            "f 7/7 8/8 9/9 10/10 11/11 12/12\n");
    const TriangleMesh m = load_obj(path);
    EXPECT_EQ(m.vertex_count(), 12u);
    EXPECT_EQ(m.triangle_count(), 8u);
    const double hexagon = 1.5 * std::sqrt(3.0);
    ASSERT_NO_FATAL_FAILURE(
        check_mesh(m, {.tangent_cos = 0.999, .area = hexagon + 3.0, .area_tolerance = 1e-5}));
    for (size_t i = 0; i < m.vertex_count(); ++i) EXPECT_EQ(normal(m, i), (Vec3{0, 1, 0}));
}

TEST_F(ObjFiles, DegenerateTexcoordsStillGiveATangent) {
    // All corners share one uv: no dP/du anywhere, yet the frame must be complete.
    const auto path = write("flat_uv.obj",
                            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5 0.5\nvn 0 0 1\n"
                            "f 1/1/1 2/1/1 3/1/1\n");
    const TriangleMesh m = load_obj(path);
    ASSERT_EQ(m.vertex_count(), 3u);
    for (size_t i = 0; i < 3; ++i) {
        EXPECT_NEAR(length(tangent(m, i)), 1.0, 1e-6);
        EXPECT_NEAR(dot(tangent(m, i), normal(m, i)), 0.0, 1e-6);
    }
}

TEST_F(ObjFiles, MissingTexcoordsAreAnError) {
    const auto path = write("bare.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    EXPECT_EQ(test::error_of([&] { load_obj(path); }),
              path.string() + ": no texture coordinates (a BTF needs uv)");

    const auto partial = write("partial.obj",
                               "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                               "f 1/1 2/2 3/3\n"
                               "f 1 3 2\n");
    EXPECT_EQ(test::error_of([&] { load_obj(partial); }),
              partial.string() + ": line 8: face has no texture coordinates (a BTF needs uv)");
}

TEST_F(ObjFiles, MissingFileIsAnError) {
    const auto path = m_folder.path() / "absent.obj";
    EXPECT_EQ(test::error_of([&] { load_obj(path); }), path.string() + ": no such file");
}

TEST_F(ObjFiles, BadIndicesNameTheLine) {
    const std::string header =
        "# cloth\n"
        "v -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "f 1/1 2/2 3/3\n";  // line 10, valid
    const auto triangle = write("bad_triangle.obj", header + "f 1/1 3/3 40/4\n");
    EXPECT_EQ(test::error_of([&] { load_obj(triangle); }),
              triangle.string() + ": line 11: face refers to vertex 40 of 4");

    // tinyobjloader drops a quad with a bad index (with a warning); it must still be an error.
    const auto quad = write("bad_quad.obj", header + "\n\nf 1/1 2/2 3/3 9/4\n");
    EXPECT_EQ(test::error_of([&] { load_obj(quad); }),
              quad.string() + ": line 13: face refers to vertex 9 of 4");

    const auto texcoord = write("bad_texcoord.obj", header + "f 1/1 3/3 4/5\n");
    EXPECT_EQ(test::error_of([&] { load_obj(texcoord); }),
              texcoord.string() + ": line 11: face refers to texture coordinate 5 of 4");

    const auto normal_index = write("bad_normal.obj", header + "vn 0 1 0\nf 1/1/1 3/3/2 4/4/1\n");
    EXPECT_EQ(test::error_of([&] { load_obj(normal_index); }),
              normal_index.string() + ": line 12: face refers to normal 2 of 1");

    const auto two = write("two_corners.obj", header + "f 1/1 2/2\n");
    EXPECT_EQ(test::error_of([&] { load_obj(two); }),
              two.string() + ": line 11: face has 2 corners (a face needs at least 3)");

    const auto zero = write("zero.obj", header + "f 0/1 2/2 3/3\n");
    const std::string message = test::error_of([&] { load_obj(zero); });
    EXPECT_EQ(message.rfind(zero.string() + ": ", 0), 0u) << message;
    EXPECT_NE(message.find("line 11"), std::string::npos) << message;
}

TEST_F(ObjFiles, FileWithoutFacesIsAnError) {
    const auto path = write("points.obj", "v 0 0 0\nvt 0 0\n");
    EXPECT_EQ(test::error_of([&] { load_obj(path); }), path.string() + ": no faces");
}

// ---- transforms ------------------------------------------------------------------------------

TEST(Mesh, RotatingAPlaneTurnsItsFrame) {
    TriangleMesh m = make_plane(2.0, 2.0);
    transform(m, Transform::rotate({1, 0, 0}, 90));
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        EXPECT_NEAR(length(normal(m, i) - Vec3{0, 0, 1}), 0.0, 1e-6);  // +y turns to +z
        EXPECT_NEAR(length(tangent(m, i) - Vec3{1, 0, 0}), 0.0, 1e-6);
        EXPECT_NEAR(position(m, i).z, 0.0, 1e-6);
        EXPECT_NEAR(position(m, i).y, 2 * v_of(m, i) - 1, 1e-6);  // v now runs up
    }
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.area = 4.0}));
}

TEST(Mesh, NonUniformScaleKeepsNormalsPerpendicular) {
    // A sphere scaled to an ellipsoid with semi-axes a, b, c: its normal at p is
    // (x/a², y/b², z/c²), not the scaled sphere normal.
    const double a = 2.0, b = 1.0, c = 0.5;
    TriangleMesh m = make_sphere(1.0, 48);
    transform(m, Transform::scale({a, b, c}));
    double worst = 1;
    for (size_t i = 0; i < m.vertex_count(); ++i) {
        const Vec3 p = position(m, i);
        const Vec3 expected = normalize(Vec3{p.x / (a * a), p.y / (b * b), p.z / (c * c)});
        worst = std::min(worst, dot(normal(m, i), expected));
    }
    EXPECT_GT(worst, 1 - 1e-6);
    ASSERT_NO_FATAL_FAILURE(check_mesh(m, {.centre = origin, .tangent_cos = 0.9}));
}

TEST(Mesh, MirroringKeepsTheWindingOnTheNormalsSide) {
    TriangleMesh m = make_sphere(1.0, 16);
    transform(m, Transform::scale({-1, 1, 1}));
    for (size_t t = 0; t < m.triangle_count(); ++t) {
        const Vec3 p0 = position(m, m.indices[3 * t]);
        const Vec3 g =
            cross(position(m, m.indices[3 * t + 1]) - p0, position(m, m.indices[3 * t + 2]) - p0);
        for (size_t k = 0; k < 3; ++k) ASSERT_GT(dot(g, normal(m, m.indices[3 * t + k])), 0.0);
        ASSERT_GT(dot(g, p0), 0.0);  // and both outward
    }
}

TEST(Mesh, TransformsCompose) {
    const Transform r = Transform::rotate({0, 1, 1}, 30);
    const Transform s = Transform::scale({1, 2, 3});
    const Transform t = Transform::translate({4, 5, 6});
    const Transform all = t * r * s;
    const Vec3 p{0.3, -0.7, 1.1};
    const Vec3 expected = t.transform_point(r.transform_point(s.transform_point(p)));
    EXPECT_NEAR(length(all.transform_point(p) - expected), 0.0, 1e-12);
    EXPECT_NEAR(all.determinant(), 6.0, 1e-12);
    // Rotations follow the right-hand rule about their axis.
    const Vec3 y = Transform::rotate({0, 0, 2}, 90).transform_vector({1, 0, 0});
    EXPECT_NEAR(length(y - Vec3{0, 1, 0}), 0.0, 1e-12);

    TriangleMesh m = make_plane(1, 1);
    const auto message = test::error_of([&] { transform(m, Transform::scale({1, 0, 1})); });
    EXPECT_NE(message.find("singular"), std::string::npos);
    EXPECT_NE(test::error_of([] {
                  Transform::rotate({0, 0, 0}, 10);
              }).find("axis"),
              std::string::npos);
}

}  // namespace
}  // namespace btf::render
