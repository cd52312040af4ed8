// SPDX-License-Identifier: MIT
#include "btf/render/mesh.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>

#include "btf/util/error.h"

namespace btf::render {

namespace fs = std::filesystem;

namespace {

// ---- shared vertex helpers -------------------------------------------------------------------

Vec3 read3(const std::vector<float>& data, size_t i) {
    return {data[3 * i], data[3 * i + 1], data[3 * i + 2]};
}

void write3(std::vector<float>& data, size_t i, const Vec3& v) {
    data[3 * i] = static_cast<float>(v.x);
    data[3 * i + 1] = static_cast<float>(v.y);
    data[3 * i + 2] = static_cast<float>(v.z);
}

void push3(std::vector<float>& data, const Vec3& v) {
    data.push_back(static_cast<float>(v.x));
    data.push_back(static_cast<float>(v.y));
    data.push_back(static_cast<float>(v.z));
}

uint32_t push_vertex(TriangleMesh& mesh, const Vec3& position, const Vec3& normal,
                     const Vec3& tangent, double u, double v) {
    const auto index = static_cast<uint32_t>(mesh.vertex_count());
    push3(mesh.positions, position);
    push3(mesh.normals, normal);
    push3(mesh.tangents, tangent);
    mesh.uvs.push_back(static_cast<float>(u));
    mesh.uvs.push_back(static_cast<float>(v));
    return index;
}

void push_triangle(TriangleMesh& mesh, uint32_t a, uint32_t b, uint32_t c) {
    mesh.indices.insert(mesh.indices.end(), {a, b, c});
}

// A unit vector orthogonal to the unit vector n, for vertices whose uvs define no direction.
Vec3 any_orthogonal(const Vec3& n) {
    const Vec3 axis = std::abs(n.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    return normalize(axis - n * dot(n, axis));
}

// The component of t orthogonal to the unit normal n, normalized; any orthogonal direction when
// t has (almost) none, so the shading frame is always complete.
Vec3 orthogonal_tangent(const Vec3& t, const Vec3& n) {
    const Vec3 projected = t - n * dot(n, t);
    const double len = length(projected);
    if (!(len > 1e-6 * length(t))) return any_orthogonal(n);
    return projected / len;
}

// Embree takes 32-bit indices; refuse meshes they cannot address instead of wrapping.
void check_vertex_count(const char* what, uint64_t vertices) {
    check(vertices <= std::numeric_limits<uint32_t>::max(),
          "{}: {} vertices exceed the 32-bit index range", what, vertices);
}

// ---- parametric shapes -----------------------------------------------------------------------

// Longitude phi is measured from +x towards -z: counter-clockwise about +y by the right-hand
// rule. The seam column reuses the angle of column 0 exactly so that both copies of a seam
// vertex get bit-identical positions (a watertight seam for Embree).
double longitude(int column, int segments) {
    return 2 * kPi * static_cast<double>(column % segments) / segments;
}
Vec3 radial(double phi) {
    return {std::cos(phi), 0, -std::sin(phi)};
}
// d radial / d phi, the direction of increasing u on every shape of revolution.
Vec3 longitude_tangent(double phi) {
    return {-std::sin(phi), 0, -std::cos(phi)};
}

}  // namespace

// ---- Transform -------------------------------------------------------------------------------

Transform Transform::translate(const Vec3& offset) {
    Transform t;
    t.m[0][3] = offset.x;
    t.m[1][3] = offset.y;
    t.m[2][3] = offset.z;
    return t;
}

Transform Transform::scale(const Vec3& factors) {
    Transform t;
    t.m[0][0] = factors.x;
    t.m[1][1] = factors.y;
    t.m[2][2] = factors.z;
    return t;
}

Transform Transform::rotate(const Vec3& axis, double degrees) {
    const double len = length(axis);
    check(len > 0 && std::isfinite(len), "Transform::rotate: the rotation axis is zero");
    const Vec3 a = axis / len;
    const double c = std::cos(radians(degrees));
    const double s = std::sin(radians(degrees));
    const double k = 1 - c;
    Transform t;
    t.m[0] = {c + a.x * a.x * k, a.x * a.y * k - a.z * s, a.x * a.z * k + a.y * s, 0};
    t.m[1] = {a.y * a.x * k + a.z * s, c + a.y * a.y * k, a.y * a.z * k - a.x * s, 0};
    t.m[2] = {a.z * a.x * k - a.y * s, a.z * a.y * k + a.x * s, c + a.z * a.z * k, 0};
    return t;
}

Vec3 Transform::transform_vector(const Vec3& v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
}

Vec3 Transform::transform_point(const Vec3& p) const {
    return transform_vector(p) + Vec3{m[0][3], m[1][3], m[2][3]};
}

double Transform::determinant() const {
    const Vec3 c0{m[0][0], m[1][0], m[2][0]};
    const Vec3 c1{m[0][1], m[1][1], m[2][1]};
    const Vec3 c2{m[0][2], m[1][2], m[2][2]};
    return triple(c0, c1, c2);
}

Vec3 Transform::transform_normal(const Vec3& n) const {
    // With columns a, b, c of the linear part, M^-T = [b×c, c×a, a×b] / det. Only the direction
    // matters, so the division reduces to the sign of det, which keeps the normal on its side.
    const Vec3 a{m[0][0], m[1][0], m[2][0]};
    const Vec3 b{m[0][1], m[1][1], m[2][1]};
    const Vec3 c{m[0][2], m[1][2], m[2][2]};
    const double det = triple(a, b, c);
    check(det != 0 && std::isfinite(det), "Transform: the linear part is singular");
    const Vec3 mapped = cross(b, c) * n.x + cross(c, a) * n.y + cross(a, b) * n.z;
    return normalize(det > 0 ? mapped : -mapped);
}

Transform operator*(const Transform& a, const Transform& b) {
    Transform r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 4; ++j) {
            double sum = j == 3 ? a.m[i][3] : 0.0;
            for (int k = 0; k < 3; ++k) sum += a.m[i][k] * b.m[k][j];
            r.m[i][j] = sum;
        }
    }
    return r;
}

void transform(TriangleMesh& mesh, const Transform& xf) {
    const double det = xf.determinant();
    check(det != 0 && std::isfinite(det), "transform: the linear part is singular");
    const size_t count = mesh.vertex_count();
    check(mesh.normals.size() == 3 * count && mesh.tangents.size() == 3 * count,
          "transform: mesh has {} positions but {} normals and {} tangents", count,
          mesh.normals.size() / 3, mesh.tangents.size() / 3);
    for (size_t i = 0; i < count; ++i) {
        const Vec3 normal = xf.transform_normal(read3(mesh.normals, i));
        write3(mesh.positions, i, xf.transform_point(read3(mesh.positions, i)));
        write3(mesh.normals, i, normal);
        write3(mesh.tangents, i,
               orthogonal_tangent(xf.transform_vector(read3(mesh.tangents, i)), normal));
    }
    // A mirror turns cross(p1 - p0, p2 - p0) inside out while M^-T keeps the shading normals
    // outside; swapping two corners puts the geometric normal back on their side.
    if (det < 0) {
        for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
            std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
        }
    }
}

// ---- generators ------------------------------------------------------------------------------

TriangleMesh make_plane(double width, double depth) {
    check(width > 0 && depth > 0, "make_plane: width and depth must be positive, got {} × {}",
          width, depth);
    const double x = width / 2;
    const double z = depth / 2;
    const Vec3 up{0, 1, 0};
    const Vec3 tangent{1, 0, 0};
    TriangleMesh mesh;
    // v grows towards -z: with normal +y and tangent +x the renderer's bitangent is
    // cross(+y, +x) = -z, and it must run along increasing v.
    const uint32_t a = push_vertex(mesh, {-x, 0, z}, up, tangent, 0, 0);
    const uint32_t b = push_vertex(mesh, {x, 0, z}, up, tangent, 1, 0);
    const uint32_t c = push_vertex(mesh, {x, 0, -z}, up, tangent, 1, 1);
    const uint32_t d = push_vertex(mesh, {-x, 0, -z}, up, tangent, 0, 1);
    push_triangle(mesh, a, b, c);
    push_triangle(mesh, a, c, d);
    return mesh;
}

TriangleMesh make_sphere(double radius, int segments) {
    check(radius > 0, "make_sphere: radius must be positive, got {}", radius);
    check(segments >= 4, "make_sphere: needs at least 4 segments, got {}", segments);
    const int rings = segments / 2;
    const uint64_t columns = static_cast<uint64_t>(segments) + 1;
    check_vertex_count("make_sphere", columns * static_cast<uint64_t>(rings - 1) + 2 * columns);

    TriangleMesh mesh;
    // v runs from the south pole (v = 0) to the north pole: with u counter-clockwise about +y,
    // that makes cross(dP/du, dP/dv) point outward.
    auto unit_point = [](double v, double phi) {
        return radial(phi) * std::sin(kPi * v) - Vec3{0, std::cos(kPi * v), 0};
    };
    // One pole vertex per segment, at the segment's middle longitude: a single shared pole
    // vertex has no defined dP/du, and u at the middle keeps the cap triangles' uvs symmetric.
    auto pole_row = [&](double v, double y) {
        const uint32_t first = static_cast<uint32_t>(mesh.vertex_count());
        for (int i = 0; i < segments; ++i) {
            const double u = (i + 0.5) / segments;
            const double phi = 2 * kPi * u;
            push_vertex(mesh, {0, y * radius, 0}, {0, y, 0}, longitude_tangent(phi), u, v);
        }
        return first;
    };
    const uint32_t south = pole_row(0.0, -1.0);
    const uint32_t first_ring = static_cast<uint32_t>(mesh.vertex_count());
    for (int j = 1; j < rings; ++j) {
        const double v = static_cast<double>(j) / rings;
        for (int i = 0; i <= segments; ++i) {
            const double phi = longitude(i, segments);
            const Vec3 n = unit_point(v, phi);
            push_vertex(mesh, n * radius, n, longitude_tangent(phi),
                        static_cast<double>(i) / segments, v);
        }
    }
    const uint32_t north = pole_row(1.0, 1.0);

    const auto stride = static_cast<uint32_t>(segments + 1);
    auto ring = [&](int j, int i) {
        return first_ring + static_cast<uint32_t>(j - 1) * stride + static_cast<uint32_t>(i);
    };
    for (int i = 0; i < segments; ++i) {
        push_triangle(mesh, south + static_cast<uint32_t>(i), ring(1, i + 1), ring(1, i));
    }
    for (int j = 1; j + 1 < rings; ++j) {
        for (int i = 0; i < segments; ++i) {
            push_triangle(mesh, ring(j, i), ring(j, i + 1), ring(j + 1, i + 1));
            push_triangle(mesh, ring(j, i), ring(j + 1, i + 1), ring(j + 1, i));
        }
    }
    for (int i = 0; i < segments; ++i) {
        push_triangle(mesh, ring(rings - 1, i), ring(rings - 1, i + 1),
                      north + static_cast<uint32_t>(i));
    }
    return mesh;
}

namespace {

// A (columns + 1) × (rows + 1) vertex grid over uv ∈ [0, 1]², two triangles per cell, counter-
// clockwise in uv. `vertex(i, j, u, v)` adds the vertex of column i, row j. With an
// orientation-preserving parametrization, counter-clockwise in uv is counter-clockwise seen from
// outside.
template <typename AddVertex>
TriangleMesh make_grid(int columns, int rows, AddVertex&& vertex) {
    TriangleMesh mesh;
    for (int j = 0; j <= rows; ++j) {
        for (int i = 0; i <= columns; ++i) {
            vertex(mesh, i, j, static_cast<double>(i) / columns, static_cast<double>(j) / rows);
        }
    }
    const auto stride = static_cast<uint32_t>(columns + 1);
    auto at = [&](int i, int j) {
        return static_cast<uint32_t>(j) * stride + static_cast<uint32_t>(i);
    };
    for (int j = 0; j < rows; ++j) {
        for (int i = 0; i < columns; ++i) {
            push_triangle(mesh, at(i, j), at(i + 1, j), at(i + 1, j + 1));
            push_triangle(mesh, at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    return mesh;
}

}  // namespace

TriangleMesh make_cylinder(double radius, double height, int segments) {
    check(radius > 0 && height > 0,
          "make_cylinder: radius and height must be positive, got {} and {}", radius, height);
    check(segments >= 3, "make_cylinder: needs at least 3 segments, got {}", segments);
    // Rows make the quads about square: long slivers give Embree's BVH loose boxes. Capped so a
    // needle-thin cylinder cannot ask for unbounded memory.
    const double rows_wanted = height * segments / (2 * kPi * radius);
    const int rows = static_cast<int>(std::clamp(std::round(rows_wanted), 1.0, 8.0 * segments));
    check_vertex_count("make_cylinder",
                       (static_cast<uint64_t>(segments) + 1) * (static_cast<uint64_t>(rows) + 1));
    return make_grid(segments, rows, [&](TriangleMesh& mesh, int i, int, double u, double v) {
        const double phi = longitude(i, segments);
        const Vec3 n = radial(phi);
        push_vertex(mesh, n * radius + Vec3{0, (v - 0.5) * height, 0}, n, longitude_tangent(phi), u,
                    v);
    });
}

TriangleMesh make_torus(double major_radius, double minor_radius, int major_segments,
                        int minor_segments) {
    check(minor_radius > 0 && major_radius > minor_radius,
          "make_torus: needs 0 < minor radius < major radius, got minor {} and major {}",
          minor_radius, major_radius);
    check(major_segments >= 3 && minor_segments >= 3,
          "make_torus: needs at least 3 segments each way, got {} × {}", major_segments,
          minor_segments);
    check_vertex_count("make_torus", (static_cast<uint64_t>(major_segments) + 1) *
                                         (static_cast<uint64_t>(minor_segments) + 1));
    return make_grid(major_segments, minor_segments,
                     [&](TriangleMesh& mesh, int i, int j, double u, double v) {
                         const double phi = longitude(i, major_segments);
                         // psi = pi + 2 pi v: the v seam sits on the inner equator, and increasing
                         // v turns down from there (outer equator at v = 0.5), which makes the
                         // parametrization orientation-preserving.
                         const double psi = kPi + longitude(j, minor_segments);
                         const Vec3 out = radial(phi);
                         const Vec3 n = out * std::cos(psi) + Vec3{0, std::sin(psi), 0};
                         push_vertex(mesh, out * major_radius + n * minor_radius, n,
                                     longitude_tangent(phi), u, v);
                     });
}

// ---- OBJ files -------------------------------------------------------------------------------

namespace {

// The surface's appearance is the BTF, so .mtl files are neither needed nor required to exist.
class IgnoreMaterials : public tinyobj::MaterialReader {
  public:
    bool operator()(const std::string&, std::vector<tinyobj::material_t>*,
                    std::map<std::string, int>*, std::string*, std::string*) override {
        return true;
    }
};

struct ObjData {
    tinyobj::attrib_t attrib;
    std::vector<tinyobj::shape_t> shapes;
    std::string warnings;  // the geometric ones only (see geometry_warnings)
};

// tinyobjloader's messages end in newlines (and one in "\n."); the exception takes one line.
std::string one_line(const std::string& text) {
    std::string out;
    std::istringstream lines(text);
    std::string line;
    while (std::getline(lines, line)) {
        const auto first = line.find_first_not_of(" \t\r.");
        if (first == std::string::npos) continue;
        const auto last = line.find_last_not_of(" \t\r");
        if (!out.empty()) out += "; ";
        out += line.substr(first, last - first + 1);
    }
    return out;
}

// Warnings about materials and group names concern nothing load_obj uses; the rest (degenerate
// faces, indices out of range) mean the geometry is not what the file's author meant.
std::string geometry_warnings(const std::string& warnings) {
    std::string kept;
    std::istringstream lines(warnings);
    std::string line;
    while (std::getline(lines, line)) {
        if (line.find("material") != std::string::npos ||
            line.find("mtllib") != std::string::npos ||
            line.find("group name") != std::string::npos) {
            continue;
        }
        kept += line + "\n";
    }
    return one_line(kept);
}

ObjData parse_obj(const fs::path& path, bool triangulate) {
    const std::string name = path.string();
    std::error_code ec;
    if (!fs::exists(path, ec)) fail("{}: no such file", name);
    if (!fs::is_regular_file(path, ec)) fail("{}: not a file", name);
    std::ifstream in(path);
    if (!in) fail("{}: cannot open for reading: {}", name, std::strerror(errno));

    ObjData data;
    std::vector<tinyobj::material_t> materials;
    std::string warnings;
    std::string errors;
    IgnoreMaterials no_materials;
    const bool ok = tinyobj::LoadObj(&data.attrib, &data.shapes, &materials, &warnings, &errors,
                                     &in, &no_materials, triangulate, false);
    if (!ok || !errors.empty()) {
        fail("{}: {}", name, errors.empty() ? "cannot parse as OBJ" : one_line(errors));
    }
    data.warnings = geometry_warnings(warnings);
    return data;
}

// The line number and corner count of each face statement, in file order. tinyobjloader reports
// neither per face; these let an error point at the offending line.
struct FaceLine {
    size_t line = 0;
    size_t corners = 0;
};

std::vector<FaceLine> face_lines(const fs::path& path) {
    std::vector<FaceLine> faces;
    std::ifstream in(path);
    std::string text;
    size_t number = 0;
    while (std::getline(in, text)) {
        ++number;
        const auto start = text.find_first_not_of(" \t");
        if (start == std::string::npos || text[start] != 'f') continue;
        if (start + 1 >= text.size() || (text[start + 1] != ' ' && text[start + 1] != '\t')) {
            continue;
        }
        std::istringstream tokens(text.substr(start + 1));
        std::string token;
        size_t corners = 0;
        while (tokens >> token) ++corners;
        faces.push_back({number, corners});
    }
    return faces;
}

// What is wrong with one face corner, or "" if nothing. `kind` names the attribute.
std::string index_problem(int index, size_t count, const char* kind) {
    if (index >= 0 && static_cast<size_t>(index) < count) return {};
    if (index < 0) return fmt::format("face refers to a {} before the first", kind);
    return fmt::format("face refers to {} {} of {}", kind, index + 1, count);
}

std::string corner_problem(const tinyobj::index_t& corner, const tinyobj::attrib_t& attrib) {
    std::string problem = index_problem(corner.vertex_index, attrib.vertices.size() / 3, "vertex");
    if (!problem.empty()) return problem;
    if (corner.texcoord_index == -1) return "face has no texture coordinates (a BTF needs uv)";
    problem =
        index_problem(corner.texcoord_index, attrib.texcoords.size() / 2, "texture coordinate");
    if (!problem.empty()) return problem;
    if (corner.normal_index == -1) return {};
    return index_problem(corner.normal_index, attrib.normals.size() / 3, "normal");
}

// Called once the triangulated read showed a problem: reads the file again untriangulated, so
// that faces match the file's face statements one to one, and names the first bad face's line.
[[noreturn]] void fail_at_face(const fs::path& path, const std::string& problem_summary) {
    const std::string name = path.string();
    const std::vector<FaceLine> lines = face_lines(path);
    for (const FaceLine& face : lines) {
        if (face.corners < 3) {
            fail("{}: line {}: face has {} corners (a face needs at least 3)", name, face.line,
                 face.corners);
        }
    }
    const ObjData data = parse_obj(path, false);
    size_t face_index = 0;
    for (const auto& shape : data.shapes) {
        size_t corner = 0;
        for (const unsigned char corners : shape.mesh.num_face_vertices) {
            if (face_index >= lines.size() || corner + corners > shape.mesh.indices.size()) break;
            for (size_t k = 0; k < corners; ++k) {
                const std::string problem =
                    corner_problem(shape.mesh.indices[corner + k], data.attrib);
                if (!problem.empty()) {
                    fail("{}: line {}: {}", name, lines[face_index].line, problem);
                }
            }
            corner += corners;
            ++face_index;
        }
    }
    fail("{}: {}", name, problem_summary);
}

struct CornerKey {
    int position, normal, texcoord;
    bool operator==(const CornerKey&) const = default;
};

struct CornerKeyHash {
    size_t operator()(const CornerKey& k) const {
        uint64_t h = static_cast<uint32_t>(k.position);
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<uint32_t>(k.normal);
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<uint32_t>(k.texcoord);
        return static_cast<size_t>(h ^ (h >> 29));
    }
};

}  // namespace

TriangleMesh load_obj(const fs::path& path) {
    const std::string name = path.string();
    const ObjData data = parse_obj(path, true);
    const tinyobj::attrib_t& attrib = data.attrib;

    std::vector<tinyobj::index_t> corners;
    for (const auto& shape : data.shapes) {
        corners.insert(corners.end(), shape.mesh.indices.begin(), shape.mesh.indices.end());
    }
    if (corners.empty() && data.warnings.empty()) fail("{}: no faces", name);
    if (attrib.texcoords.empty()) fail("{}: no texture coordinates (a BTF needs uv)", name);
    bool valid = data.warnings.empty() && corners.size() % 3 == 0;
    for (const auto& corner : corners) valid = valid && corner_problem(corner, attrib).empty();
    if (!valid) {
        fail_at_face(path, data.warnings.empty() ? "invalid face indices" : data.warnings);
    }

    const size_t position_count = attrib.vertices.size() / 3;
    auto position = [&](int i) {
        const auto k = static_cast<size_t>(i);
        return Vec3{attrib.vertices[3 * k], attrib.vertices[3 * k + 1], attrib.vertices[3 * k + 2]};
    };

    // Area-weighted normals per position: |cross| is twice the area, so summing the unnormalized
    // cross products weights each face by its area.
    std::vector<Vec3> position_normals(position_count);
    for (size_t t = 0; t < corners.size(); t += 3) {
        const Vec3 p0 = position(corners[t].vertex_index);
        const Vec3 face = cross(position(corners[t + 1].vertex_index) - p0,
                                position(corners[t + 2].vertex_index) - p0);
        for (size_t k = 0; k < 3; ++k) {
            position_normals[static_cast<size_t>(corners[t + k].vertex_index)] += face;
        }
    }
    auto computed_normal = [&](int i) {
        const Vec3 sum = position_normals[static_cast<size_t>(i)];
        const double len = length(sum);
        // Only faces of zero area touch this position, so there is no surface to be normal to.
        return len > 0 ? sum / len : Vec3{0, 1, 0};
    };

    TriangleMesh mesh;
    std::unordered_map<CornerKey, uint32_t, CornerKeyHash> vertex_of;
    mesh.indices.reserve(corners.size());
    for (const auto& corner : corners) {
        const CornerKey key{corner.vertex_index, corner.normal_index, corner.texcoord_index};
        const auto [it, added] =
            vertex_of.try_emplace(key, static_cast<uint32_t>(mesh.vertex_count()));
        if (added) {
            check_vertex_count(name.c_str(), static_cast<uint64_t>(mesh.vertex_count()) + 1);
            Vec3 normal = computed_normal(corner.vertex_index);
            if (corner.normal_index >= 0) {
                const auto k = static_cast<size_t>(corner.normal_index);
                const Vec3 file{attrib.normals[3 * k], attrib.normals[3 * k + 1],
                                attrib.normals[3 * k + 2]};
                const double len = length(file);
                if (len > 0 && std::isfinite(len)) normal = file / len;
            }
            const auto k = static_cast<size_t>(corner.texcoord_index);
            push_vertex(mesh, position(corner.vertex_index), normal, {}, attrib.texcoords[2 * k],
                        attrib.texcoords[2 * k + 1]);
        }
        mesh.indices.push_back(it->second);
    }

    // Tangents: each triangle's dP/du from the inverse of its 2 × 2 uv-delta matrix,
    // accumulated as area-weighted unit directions so that triangles with tiny uv extents (huge
    // |dP/du|) do not outvote their neighbours.
    std::vector<Vec3> tangent_sums(mesh.vertex_count());
    auto uv = [&](uint32_t i) {
        return std::pair<double, double>{mesh.uvs[2 * i], mesh.uvs[2 * i + 1]};
    };
    for (size_t t = 0; t < mesh.indices.size(); t += 3) {
        const uint32_t i0 = mesh.indices[t], i1 = mesh.indices[t + 1], i2 = mesh.indices[t + 2];
        const Vec3 p0 = read3(mesh.positions, i0);
        const Vec3 e1 = read3(mesh.positions, i1) - p0;
        const Vec3 e2 = read3(mesh.positions, i2) - p0;
        const auto [u0, v0] = uv(i0);
        const auto [u1, v1] = uv(i1);
        const auto [u2, v2] = uv(i2);
        const double du1 = u1 - u0, dv1 = v1 - v0, du2 = u2 - u0, dv2 = v2 - v0;
        const double det = du1 * dv2 - du2 * dv1;
        // Relative test: the uv edges are (nearly) parallel, at float precision of the uvs.
        const double scale = std::hypot(du1, dv1) * std::hypot(du2, dv2);
        const double area = 0.5 * length(cross(e1, e2));
        if (!(std::abs(det) > 1e-6 * scale) || !(area > 0)) continue;
        const Vec3 dpdu = (e1 * dv2 - e2 * dv1) / det;
        const double len = length(dpdu);
        if (!(len > 0) || !std::isfinite(len)) continue;
        const Vec3 weighted = dpdu * (area / len);
        tangent_sums[i0] += weighted;
        tangent_sums[i1] += weighted;
        tangent_sums[i2] += weighted;
    }
    for (size_t i = 0; i < mesh.vertex_count(); ++i) {
        write3(mesh.tangents, i, orthogonal_tangent(tangent_sums[i], read3(mesh.normals, i)));
    }
    return mesh;
}

}  // namespace btf::render
