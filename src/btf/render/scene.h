// SPDX-License-Identifier: MIT
#pragma once
/// A scene for the CPU renderer: a pinhole camera, triangle-mesh objects with surfaces and a uv
/// mapping, and lights, with Embree 3 answering the ray queries. Scenes are usually read from
/// JSON (scene_file.h, documented in docs/scenes.md); tests build them in code.
///
/// World space is right-handed with +y up. A hit's shading frame follows docs/conventions.md: z =
/// the interpolated shading normal, x = the tangent, the direction of increasing (mapped) u, made
/// orthogonal to z, y = z × x. Surfaces are two-sided: seen from behind, the frame is flipped
/// (z and y negated), so a cloth's inside shows the same material.

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "btf/core/material.h"
#include "btf/core/math.h"
#include "btf/render/lights.h"
#include "btf/render/mesh.h"
#include "btf/render/surface.h"

namespace btf::render {

struct Ray {
    Vec3 origin, direction;  ///< direction is unit length
};

/// A pinhole camera. `fov` is the vertical field of view in degrees; pixel (0, 0) is the top left.
struct Camera {
    Vec3 position{0, 1, 4}, look_at{0, 0, 0}, up{0, 1, 0};
    double fov = 40;
    int width = 512, height = 512;
    /// The ray through image position (x, y) in pixels (x, y ∈ [0, width) × [0, height)).
    Ray ray(double x, double y) const;
};

/// How texture coordinates of a mesh map onto its material: uv' = R(rotation) · (u · scale_u,
/// v · scale_v). The tangent turns with the rotation, so a BTF's φ stays measured from the
/// direction of increasing u' (exact for meshes whose uv parametrization is conformal up to the
/// scale, which all generated shapes are away from the sphere's poles).
struct UvMapping {
    double scale_u = 1, scale_v = 1;
    double rotation = 0;  ///< degrees, counter-clockwise in the uv plane
};

struct SceneObject {
    std::string name;
    TriangleMesh mesh;  ///< in world space
    std::shared_ptr<const Surface> surface;
    UvMapping uv;
};

/// Where a ray meets the scene.
struct Hit {
    double distance = std::numeric_limits<double>::infinity();
    int object = -1;        ///< index into objects(), or -1
    int sphere_light = -1;  ///< index into sphere_lights() when the ray hit an emitter
    Vec3 position;
    Vec3 geometric_normal;            ///< unit, facing the ray's origin
    Vec3 normal, tangent, bitangent;  ///< the shading frame (see the file comment)
    Uv uv;                            ///< mapped texture position (wrapped by the material)
    bool found() const { return object >= 0 || sphere_light >= 0; }
    Vec3 to_local(const Vec3& w) const {
        return {dot(w, tangent), dot(w, bitangent), dot(w, normal)};
    }
    Vec3 to_world(const Vec3& w) const { return tangent * w.x + bitangent * w.y + normal * w.z; }
};

class Scene {
  public:
    Scene();
    ~Scene();
    Scene(Scene&&) noexcept;
    Scene& operator=(Scene&&) noexcept;

    Camera camera;

    void add_object(SceneObject object);
    void add_light(std::shared_ptr<const Light> light);
    /// Builds the acceleration structure; call after the last add_object() and before tracing.
    void commit();

    /// The closest hit along the ray within (0, max_distance), objects and sphere lights.
    Hit intersect(const Ray& ray,
                  double max_distance = std::numeric_limits<double>::infinity()) const;
    /// Whether anything blocks the ray before max_distance (objects and sphere lights but
    /// `except`, the light a shadow ray goes to).
    bool occluded(const Ray& ray, double max_distance, const Light* except = nullptr) const;
    /// A ray leaving `hit` in world direction `d`, offset so that it does not hit its own surface.
    Ray spawn(const Hit& hit, const Vec3& d) const;

    const std::vector<SceneObject>& objects() const { return m_objects; }
    std::vector<SceneObject>& objects() { return m_objects; }
    const std::vector<std::shared_ptr<const Light>>& lights() const { return m_lights; }
    const std::vector<const SphereLight*>& sphere_lights() const { return m_spheres; }
    /// The environment light, if the scene has one (at most one).
    const EnvironmentLight* environment() const { return m_environment; }

  private:
    struct Accel;
    std::unique_ptr<Accel> m_accel;
    std::vector<SceneObject> m_objects;
    std::vector<std::shared_ptr<const Light>> m_lights;
    std::vector<const SphereLight*> m_spheres;
    const EnvironmentLight* m_environment = nullptr;
    double m_epsilon = 1e-4;
};

}  // namespace btf::render
