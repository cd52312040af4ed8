// SPDX-License-Identifier: MIT
#include "btf/render/scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "btf/util/error.h"

namespace btf::render {

Ray Camera::ray(double x, double y) const {
    const Vec3 forward = normalize(look_at - position);
    const Vec3 right = normalize(cross(forward, up));
    const Vec3 true_up = cross(right, forward);
    const double tan_half = std::tan(radians(fov) / 2);
    const double aspect = double(width) / height;
    const double sx = (2 * x / width - 1) * tan_half * aspect;
    const double sy = (1 - 2 * y / height) * tan_half;
    return {position, normalize(forward + right * sx + true_up * sy)};
}

struct Scene::Accel {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    ~Accel() {
        if (scene) rtcReleaseScene(scene);
        if (device) rtcReleaseDevice(device);
    }
};

Scene::Scene() = default;
Scene::~Scene() = default;
Scene::Scene(Scene&&) noexcept = default;
Scene& Scene::operator=(Scene&&) noexcept = default;

void Scene::add_object(SceneObject object) {
    if (!object.surface) throw Error(object.name + ": object has no surface");
    if (object.mesh.indices.empty()) throw Error(object.name + ": object has no triangles");
    m_objects.push_back(std::move(object));
    m_accel.reset();
}

void Scene::add_light(std::shared_ptr<const Light> light) {
    const Light* raw = light.get();
    if (const auto* env = dynamic_cast<const EnvironmentLight*>(raw)) {
        if (m_environment) throw Error("a scene has at most one environment light");
        m_environment = env;
    }
    m_lights.push_back(std::move(light));
    if (const auto* sphere = dynamic_cast<const SphereLight*>(raw)) m_spheres.push_back(sphere);
}

void Scene::commit() {
    auto accel = std::make_unique<Accel>();
    accel->device = rtcNewDevice(nullptr);
    if (!accel->device) throw Error("Embree: cannot create a device");
    accel->scene = rtcNewScene(accel->device);
    double extent = 1;
    for (size_t i = 0; i < m_objects.size(); ++i) {
        const TriangleMesh& mesh = m_objects[i].mesh;
        RTCGeometry geometry = rtcNewGeometry(accel->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* vertices = static_cast<float*>(
            rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                    3 * sizeof(float), mesh.vertex_count()));
        std::memcpy(vertices, mesh.positions.data(), mesh.positions.size() * sizeof(float));
        auto* indices = static_cast<uint32_t*>(
            rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                    3 * sizeof(uint32_t), mesh.triangle_count()));
        std::memcpy(indices, mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t));
        rtcCommitGeometry(geometry);
        rtcAttachGeometryByID(accel->scene, geometry, unsigned(i));
        rtcReleaseGeometry(geometry);
        for (float p : mesh.positions) extent = std::max(extent, double(std::abs(p)));
    }
    rtcCommitScene(accel->scene);
    if (rtcGetDeviceError(accel->device) != RTC_ERROR_NONE)
        throw Error("Embree: building the scene's acceleration structure failed");
    // Float positions: offsets a few ulps of the scene's extent keep rays off their own surface.
    m_epsilon = 2e-5 * extent;
    m_accel = std::move(accel);
}

namespace {

RTCRay embree_ray(const Ray& ray, double max_distance) {
    RTCRay r{};
    r.org_x = float(ray.origin.x), r.org_y = float(ray.origin.y), r.org_z = float(ray.origin.z);
    r.dir_x = float(ray.direction.x), r.dir_y = float(ray.direction.y),
    r.dir_z = float(ray.direction.z);
    r.tnear = 0;
    r.tfar = std::isfinite(max_distance) ? float(max_distance) : INFINITY;
    r.mask = ~0u;
    r.flags = 0;
    return r;
}

Vec3 vertex3(const std::vector<float>& v, uint32_t i) {
    return {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
}

}  // namespace

Hit Scene::intersect(const Ray& ray, double max_distance) const {
    if (!m_accel) throw Error("Scene::intersect before commit()");
    Hit hit;
    RTCRayHit rh{};
    rh.ray = embree_ray(ray, max_distance);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcIntersect1(m_accel->scene, &context, &rh);
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        hit.distance = rh.ray.tfar;
        hit.object = int(rh.hit.geomID);
    }
    for (size_t s = 0; s < m_spheres.size(); ++s) {
        const double t = m_spheres[s]->intersect(ray.origin, ray.direction);
        if (t < hit.distance && t < max_distance) {
            hit.distance = t;
            hit.object = -1;
            hit.sphere_light = int(s);
        }
    }
    if (hit.object < 0) {
        if (hit.sphere_light >= 0) hit.position = ray.origin + ray.direction * hit.distance;
        return hit;
    }

    const SceneObject& object = m_objects[size_t(hit.object)];
    const TriangleMesh& mesh = object.mesh;
    const uint32_t* tri = &mesh.indices[3 * size_t(rh.hit.primID)];
    const double b1 = rh.hit.u, b2 = rh.hit.v, b0 = 1 - b1 - b2;
    auto lerp3 = [&](const std::vector<float>& v) {
        return vertex3(v, tri[0]) * b0 + vertex3(v, tri[1]) * b1 + vertex3(v, tri[2]) * b2;
    };
    hit.position = ray.origin + ray.direction * hit.distance;
    Vec3 ng = normalize(Vec3{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z});
    Vec3 n = lerp3(mesh.normals);
    n = length(n) > 0 ? normalize(n) : ng;
    if (dot(ng, n) < 0) ng = -ng;  // the geometric normal on the shading normal's side
    Vec3 t = lerp3(mesh.tangents);
    const double u =
        mesh.uvs[2 * tri[0]] * b0 + mesh.uvs[2 * tri[1]] * b1 + mesh.uvs[2 * tri[2]] * b2;
    const double v = mesh.uvs[2 * tri[0] + 1] * b0 + mesh.uvs[2 * tri[1] + 1] * b1 +
                     mesh.uvs[2 * tri[2] + 1] * b2;
    if (dot(ng, ray.direction) > 0) {  // seen from behind: the two-sided flip
        n = -n;
        ng = -ng;
    }
    t = t - n * dot(t, n);
    if (length(t) < 1e-8) {
        Vec3 s, b;
        orthonormal_basis(n, s, b);
        t = s;
    }
    t = normalize(t);
    Vec3 b = cross(n, t);

    const UvMapping& map = object.uv;
    const double rot = radians(map.rotation), c = std::cos(rot), s = std::sin(rot);
    const double su = u * map.scale_u, sv = v * map.scale_v;
    hit.uv = {c * su - s * sv, s * su + c * sv};
    if (map.rotation != 0 || map.scale_u != map.scale_v) {
        // dP/du' = dP/du · c / scale_u − dP/dv · s / scale_v, with the smooth frame's directions
        // (dP/dv taken perpendicular to dP/du, on the side the triangle's dP/dv points to) and
        // the triangle's lengths of dP/du and dP/dv (which differ wherever the mesh's uv
        // parametrization stretches, as around a cylinder).
        const Vec3 p0 = vertex3(mesh.positions, tri[0]);
        const Vec3 e1 = vertex3(mesh.positions, tri[1]) - p0,
                   e2 = vertex3(mesh.positions, tri[2]) - p0;
        const auto uv_of = [&](int k, int axis) { return double(mesh.uvs[2 * tri[k] + axis]); };
        const double du1 = uv_of(1, 0) - uv_of(0, 0), dv1 = uv_of(1, 1) - uv_of(0, 1);
        const double du2 = uv_of(2, 0) - uv_of(0, 0), dv2 = uv_of(2, 1) - uv_of(0, 1);
        const double det = du1 * dv2 - du2 * dv1;
        double len_u = 1, len_v = 1;
        Vec3 along_v = b;  // the direction of increasing v: b, unless seen from behind or mirrored
        if (std::abs(det) > 1e-20) {
            const Vec3 dpdv = (e2 * du1 - e1 * du2) / det;
            len_u = length((e1 * dv2 - e2 * dv1) / det);
            len_v = length(dpdv);
            if (dot(dpdv, b) < 0) along_v = -b;
        }
        t = normalize(t * (c * len_u / map.scale_u) - along_v * (s * len_v / map.scale_v));
        b = cross(n, t);
    }
    hit.geometric_normal = ng;
    hit.normal = n;
    hit.tangent = t;
    hit.bitangent = b;
    return hit;
}

bool Scene::occluded(const Ray& ray, double max_distance, const Light* except) const {
    if (!m_accel) throw Error("Scene::occluded before commit()");
    for (const SphereLight* sphere : m_spheres)
        if (sphere != except && sphere->intersect(ray.origin, ray.direction) < max_distance)
            return true;
    RTCRay r = embree_ray(ray, max_distance);
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcOccluded1(m_accel->scene, &context, &r);
    return r.tfar < 0;  // Embree sets tfar to -inf on a hit
}

Ray Scene::spawn(const Hit& hit, const Vec3& d) const {
    const Vec3 offset =
        hit.geometric_normal * (dot(d, hit.geometric_normal) >= 0 ? m_epsilon : -m_epsilon);
    return {hit.position + offset, d};
}

}  // namespace btf::render
