// SPDX-License-Identifier: MIT
#pragma once
/// Triangle meshes for the path tracer: generated test shapes (plane, sphere, cylinder, torus),
/// meshes read from Wavefront OBJ files, and affine transforms of them. The buffers are the
/// float arrays the renderer hands to Embree as they are.
///
/// Conventions:
/// - World: right-handed, +y up. Every generator centres its shape at the origin; object
///   placement is the job of transform() (or the renderer's own instancing).
/// - Winding: indices are counter-clockwise seen from outside, so the geometric normal
///   cross(p1 - p0, p2 - p0) points outward, to the same side as the shading normals.
/// - BTF frame: the material's local frame has z = shading normal and x = tangent = the
///   direction of increasing u (dP/du, made orthogonal to the normal). The renderer takes
///   bitangent = cross(normal, tangent), so (tangent, bitangent, normal) is right-handed.
/// - uv orientation: u runs along the BTF image's columns and v along its rows. Every
///   generated shape is parametrized orientation-preserving, i.e. cross(dP/du, dP/dv) points
///   along the outward normal, which is the same as dP/dv having a positive component along
///   cross(normal, tangent). The renderer's bitangent therefore runs towards increasing v and
///   the BTF image is never mirrored on the surface. Seen from outside with v pointing up, u
///   points right on every shape, as in the usual OBJ texture convention (v = 0 at the bottom
///   of the image).
///   - plane: u along +x, v along -z (towards -z; normal +y, tangent +x, cross(+y, +x) = -z).
///   - sphere, cylinder, torus: u is the longitude phi around +y, counter-clockwise seen from
///     above (right-hand rule about +y; from +x towards -z), starting at +x.
///   - sphere: v from the south pole (v = 0, y = -r) to the north pole (v = 1, y = +r).
///   - cylinder: v from the bottom rim (v = 0, y = -h/2) to the top rim (v = 1, y = +h/2).
///   - torus: v is the angle around the tube, running from the inner equator (v = 0) down over
///     the bottom (v = 0.25), the outer equator (v = 0.5) and the top (v = 0.75) back to the
///     inner equator; the v seam lies on the inner equator, the least visible ring.
/// - Seams: the vertices on a seam (u = 0/1, and v = 0/1 on the torus) are duplicated, so uv
///   never wraps inside a triangle. At the sphere's poles each segment has its own pole vertex
///   (u at the middle of the segment) whose tangent is the finite longitude direction there.
/// - uv: generated shapes have uv in [0, 1] covering the whole surface once; repetition and
///   rotation of the material are the renderer's business. load_obj() passes the file's
///   texture coordinates through unchanged (they may lie outside [0, 1]).

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "btf/core/math.h"

namespace btf::render {

/// An indexed triangle mesh with per-vertex shading frame and texture coordinates.
struct TriangleMesh {
    std::vector<float> positions;   ///< xyz per vertex
    std::vector<float> normals;     ///< unit shading normal per vertex (xyz)
    std::vector<float> uvs;         ///< uv per vertex (u along image columns, v along rows)
    std::vector<float> tangents;    ///< unit dP/du per vertex, orthogonal to the normal (xyz)
    std::vector<uint32_t> indices;  ///< 3 per triangle, counter-clockwise seen from outside

    /// Number of vertices (positions.size() / 3).
    size_t vertex_count() const { return positions.size() / 3; }
    /// Number of triangles (indices.size() / 3).
    size_t triangle_count() const { return indices.size() / 3; }
};

/// An affine transform: a 4 × 4 matrix whose last row is (0, 0, 0, 1), stored as its upper
/// 3 × 4 part, row-major: m[row][0..2] is the linear part, m[row][3] the translation. Points are
/// column vectors: p' = M p.
struct Transform {
    std::array<std::array<double, 4>, 3> m = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};

    /// The identity.
    static Transform identity() { return {}; }
    /// Translation by `offset`.
    static Transform translate(const Vec3& offset);
    /// Scaling by `factors` along x, y and z (a negative factor mirrors).
    static Transform scale(const Vec3& factors);
    /// Rotation by `degrees` about `axis` through the origin, counter-clockwise looking down the
    /// axis (right-hand rule). Throws btf::Error for a zero axis.
    static Transform rotate(const Vec3& axis, double degrees);

    /// M p (with translation).
    Vec3 transform_point(const Vec3& p) const;
    /// The linear part applied to a direction: M v (no translation), e.g. dP/du.
    Vec3 transform_vector(const Vec3& v) const;
    /// A surface normal mapped by the inverse transpose of the linear part and normalized.
    /// Throws btf::Error if the linear part is singular.
    Vec3 transform_normal(const Vec3& n) const;
    /// Determinant of the linear part (negative for a mirroring transform).
    double determinant() const;
};

/// Composition: (a * b) applies b first, then a.
Transform operator*(const Transform& a, const Transform& b);

/// A width × depth rectangle in the xz-plane facing +y (two triangles); u along +x, v along -z.
/// Throws btf::Error unless both sizes are positive.
TriangleMesh make_plane(double width, double depth);

/// A UV sphere: `segments` steps of longitude (u) and segments / 2 rings of latitude (v, south to
/// north). Throws btf::Error unless radius > 0 and segments >= 4.
TriangleMesh make_sphere(double radius, int segments);

/// The open side surface of a cylinder around +y (no caps): `segments` steps around (u), v from
/// the bottom rim to the top rim, in rows that make the quads about square (1 to 8 × segments).
/// Throws btf::Error unless radius > 0, height > 0 and segments >= 3.
TriangleMesh make_cylinder(double radius, double height, int segments);

/// A torus around +y: tube centre line of radius `major_radius` in the xz-plane, tube radius
/// `minor_radius`; u along the centre line, v around the tube (see the header comment).
/// Throws btf::Error unless 0 < minor_radius < major_radius and both segment counts are >= 3.
TriangleMesh make_torus(double major_radius, double minor_radius, int major_segments,
                        int minor_segments);

/// Reads a Wavefront OBJ file: all objects and groups merged into one mesh, polygons
/// triangulated, points, lines and materials ignored (the material is the BTF). Every face
/// corner needs a texture coordinate. Normals come from the file where a corner has one, else
/// from the area-weighted average of the geometric normals of the triangles (after
/// triangulation) around its position.
/// Tangents are the area-weighted average of the adjacent triangles' dP/du directions,
/// orthogonalized to the normal (any direction orthogonal to the normal where the uvs give
/// none). Corners with the same (position, normal, texture coordinate) indices share a vertex.
/// The file's winding and uv orientation are kept as they are: a file with mirrored uvs shows
/// the BTF mirrored. Throws btf::Error naming the file and, where it applies, the line.
TriangleMesh load_obj(const std::filesystem::path& path);

/// Transforms a mesh in place: positions by M, normals by the inverse transpose (renormalized),
/// tangents by the linear part (re-orthogonalized to the new normal). For a mirroring transform
/// (determinant < 0) the winding is reversed so that the geometric normal stays on the side of
/// the shading normals. The parametrization then becomes orientation-reversing: the renderer's
/// bitangent cross(normal, tangent) runs towards decreasing v, so the BTF's angular frame is
/// mirrored against its image (avoid mirroring transforms on anisotropic materials). Throws
/// btf::Error if the linear part is singular.
void transform(TriangleMesh& mesh, const Transform& xf);

}  // namespace btf::render
