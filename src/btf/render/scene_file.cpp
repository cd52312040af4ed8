// SPDX-License-Identifier: MIT
#include "btf/render/scene_file.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/io/sampled_material.h"
#include "btf/io/ubo2014.h"
#include "btf/util/error.h"

namespace btf::render {

using nlohmann::json;

std::shared_ptr<const Material> open_material_file(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw Error(path.string() + ": no such file");
    // A UBO2014 file: the material of its own factors (codecs/dfmf_export.h), as its package's.
    if (probe_package(path) || ubo2014::probe(path)) return open_material(path);
    return open_sampled_material(path);  // raw data; errors name the file
}

namespace {

// One JSON object of the scene and where it is, for messages.
class Node {
  public:
    Node(const json& j, std::string where, const std::string& file)
        : m_j(j), m_where(std::move(where)), m_file(file) {
        if (!m_j.is_object()) fail("expected an object");
    }

    [[noreturn]] void fail(const std::string& message) const {
        throw Error(m_file + ": " + (m_where.empty() ? "" : m_where + ": ") + message);
    }
    void allow(std::initializer_list<const char*> keys) const {
        const std::set<std::string> allowed(keys.begin(), keys.end());
        for (const auto& [key, value] : m_j.items())
            if (!allowed.count(key)) fail(fmt::format("unknown key \"{}\"", key));
    }
    bool has(const char* key) const { return m_j.contains(key); }
    std::string place(const char* key) const { return m_where.empty() ? key : m_where + "." + key; }

    double number(const char* key, double fallback, double lo = -INFINITY,
                  double hi = INFINITY) const {
        if (!has(key)) return fallback;
        const json& v = m_j.at(key);
        if (!v.is_number()) fail(fmt::format("\"{}\" must be a number", key));
        const double x = v.get<double>();
        if (!(x >= lo && x <= hi))
            fail(fmt::format("\"{}\" = {} is outside [{}, {}]", key, x, lo, hi));
        return x;
    }
    int integer(const char* key, int fallback, int lo, int hi) const {
        if (!has(key)) return fallback;
        const json& v = m_j.at(key);
        if (!v.is_number_integer()) fail(fmt::format("\"{}\" must be an integer", key));
        const int64_t x = v.get<int64_t>();
        if (x < lo || x > hi) fail(fmt::format("\"{}\" = {} is outside [{}, {}]", key, x, lo, hi));
        return int(x);
    }
    std::string string(const char* key, const std::string& fallback) const {
        if (!has(key)) return fallback;
        const json& v = m_j.at(key);
        if (!v.is_string()) fail(fmt::format("\"{}\" must be a string", key));
        return v.get<std::string>();
    }
    std::string required_string(const char* key) const {
        if (!has(key)) fail(fmt::format("\"{}\" is required", key));
        return string(key, "");
    }
    Vec3 vec3(const char* key, const Vec3& fallback) const {
        if (!has(key)) return fallback;
        const json& v = m_j.at(key);
        if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
            !v[2].is_number())
            fail(fmt::format("\"{}\" must be an array of 3 numbers", key));
        return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
    }
    /// A colour: one number (grey) or three; non-negative.
    Rgb rgb(const char* key, const Rgb& fallback) const {
        if (!has(key)) return fallback;
        const json& v = m_j.at(key);
        Vec3 c;
        if (v.is_number()) {
            const double x = v.get<double>();
            c = {x, x, x};
        } else {
            c = vec3(key, {});
        }
        if (!(c.x >= 0 && c.y >= 0 && c.z >= 0) || !std::isfinite(c.x + c.y + c.z))
            fail(fmt::format("\"{}\" must be finite and non-negative", key));
        return {float(c.x), float(c.y), float(c.z)};
    }
    /// A scale: one positive number or three.
    Vec3 scale3(const char* key) const {
        if (!has(key)) return {1, 1, 1};
        const json& v = m_j.at(key);
        const Vec3 s =
            v.is_number() ? Vec3{v.get<double>(), v.get<double>(), v.get<double>()} : vec3(key, {});
        if (!(s.x > 0 && s.y > 0 && s.z > 0)) fail(fmt::format("\"{}\" must be positive", key));
        return s;
    }
    Node child(const char* key) const {
        if (!has(key)) fail(fmt::format("\"{}\" is required", key));
        return Node(m_j.at(key), place(key), m_file);
    }
    const json& raw() const { return m_j; }
    const std::string& where() const { return m_where; }

  private:
    const json& m_j;
    std::string m_where;
    const std::string& m_file;
};

class SceneReader {
  public:
    SceneReader(const std::string& name, std::filesystem::path base, const LoadOptions& options)
        : m_name(name), m_base(std::move(base)), m_options(options) {}

    LoadedScene read(const json& root) {
        const Node top(root, "", m_name);
        top.allow({"camera", "render", "objects", "lights"});
        LoadedScene out;
        read_camera(top.child("camera"), out.scene.camera);
        if (top.has("render")) read_render(top.child("render"), out.settings);
        if (!top.has("objects")) top.fail("\"objects\" is required");
        if (!top.raw().at("objects").is_array()) top.fail("\"objects\" must be an array");
        const json& objects = top.raw().at("objects");
        for (size_t i = 0; i < objects.size(); ++i)
            out.scene.add_object(
                read_object(Node(objects[i], fmt::format("objects[{}]", i), m_name)));
        out.btf_objects = m_btf_objects;
        if (top.has("lights")) {
            const json& lights = top.raw().at("lights");
            if (!lights.is_array()) top.fail("\"lights\" must be an array");
            for (size_t i = 0; i < lights.size(); ++i)
                read_light(Node(lights[i], fmt::format("lights[{}]", i), m_name), out.scene);
        }
        out.scene.commit();
        return out;
    }

  private:
    std::filesystem::path resolve(const std::string& file) const {
        const std::filesystem::path p(file);
        return p.is_absolute() ? p : m_base / p;
    }

    void read_camera(const Node& n, Camera& camera) const {
        n.allow({"position", "look_at", "up", "fov", "width", "height"});
        camera.position = n.vec3("position", camera.position);
        camera.look_at = n.vec3("look_at", camera.look_at);
        camera.up = n.vec3("up", camera.up);
        camera.fov = n.number("fov", camera.fov, 1, 179);
        camera.width = n.integer("width", camera.width, 1, 16384);
        camera.height = n.integer("height", camera.height, 1, 16384);
        const Vec3 forward = camera.look_at - camera.position;
        if (length(forward) == 0) n.fail("\"position\" and \"look_at\" coincide");
        if (length(cross(forward, camera.up)) < 1e-9 * length(forward) * length(camera.up))
            n.fail("\"up\" is parallel to the viewing direction");
    }

    void read_render(const Node& n, SceneSettings& s) const {
        n.allow({"integrator", "spp", "time", "max_depth", "seed", "exposure", "filter"});
        const std::string integrator = n.string("integrator", "path");
        s.integrator = integrator;
        if (integrator == "direct")
            s.options.integrator.max_depth = 1;
        else if (integrator == "path")
            s.options.integrator.max_depth = n.integer("max_depth", 8, 1, 1000);
        else
            n.fail(fmt::format("unknown integrator \"{}\" (direct, path)", integrator));
        if (integrator == "direct" && n.has("max_depth"))
            n.fail("\"max_depth\" applies to the path integrator only");
        s.options.spp = n.integer("spp", s.options.spp, 0, 1 << 20);
        s.options.time_limit = n.number("time", 0, 0, 1e7);
        if (s.options.spp == 0 && s.options.time_limit == 0)
            n.fail("\"spp\" = 0 needs a \"time\" limit");
        s.options.seed = uint64_t(n.integer("seed", 1, 0, INT32_MAX));
        s.exposure = n.number("exposure", 0, -30, 30);
        const std::string filter = n.string("filter", "stochastic");
        if (filter == "stochastic")
            s.options.integrator.filter = Filter::kStochastic;
        else if (filter == "deterministic")
            s.options.integrator.filter = Filter::kDeterministic;
        else
            n.fail(fmt::format("unknown filter \"{}\" (stochastic, deterministic)", filter));
    }

    std::shared_ptr<const Surface> read_material(const Node& n) {
        const std::string type = n.required_string("type");
        if (type == "btf") {
            n.allow({"type", "file"});
            ++m_btf_objects;
            std::shared_ptr<const Material> material = m_options.btf_override;
            if (!material) {
                const std::filesystem::path file = resolve(n.required_string("file"));
                auto it = m_materials.find(file.string());
                if (it == m_materials.end()) {
                    try {
                        it = m_materials.emplace(file.string(), open_material_file(file)).first;
                    } catch (const Cancelled&) {
                        throw;
                    } catch (const Error& e) {
                        n.fail(e.what());
                    }
                }
                material = it->second;
            }
            return std::make_shared<BtfSurface>(material, m_options.sampling);
        }
        if (type == "diffuse") {
            n.allow({"type", "albedo"});
            const Rgb albedo = n.rgb("albedo", {0.5f, 0.5f, 0.5f});
            if (albedo.r > 1 || albedo.g > 1 || albedo.b > 1) n.fail("\"albedo\" must be ≤ 1");
            return std::make_shared<DiffuseSurface>(albedo);
        }
        if (type == "conductor") {
            n.allow({"type", "f0", "roughness"});
            const Rgb f0 = n.rgb("f0", {0.95f, 0.64f, 0.54f});
            if (f0.r > 1 || f0.g > 1 || f0.b > 1) n.fail("\"f0\" must be ≤ 1");
            return std::make_shared<ConductorSurface>(f0, n.number("roughness", 0.2, 0, 1));
        }
        n.fail(fmt::format("unknown material type \"{}\" (btf, diffuse, conductor)", type));
    }

    SceneObject read_object(const Node& n) {
        const std::string shape = n.required_string("shape");
        static const std::map<std::string, std::vector<const char*>> kShapeKeys = {
            {"plane", {"width", "depth"}},
            {"sphere", {"radius", "segments"}},
            {"cylinder", {"radius", "height", "segments"}},
            {"torus", {"major_radius", "minor_radius", "segments"}},
            {"obj", {"file"}},
        };
        const auto shape_keys = kShapeKeys.find(shape);
        if (shape_keys == kShapeKeys.end())
            n.fail(
                fmt::format("unknown shape \"{}\" (plane, sphere, cylinder, torus, obj)", shape));
        std::set<std::string> allowed = {"name",     "shape", "material", "position",
                                         "rotation", "scale", "uv_scale", "uv_rotation"};
        allowed.insert(shape_keys->second.begin(), shape_keys->second.end());
        for (const auto& [key, value] : n.raw().items())
            if (!allowed.count(key)) n.fail(fmt::format("unknown key \"{}\" for a {}", key, shape));

        SceneObject object;
        object.name = n.string("name", m_name + ": " + n.where());
        const int segments = n.integer("segments", 128, 3, 4096);
        if (shape == "plane") {
            object.mesh = make_plane(n.number("width", 2, 1e-9), n.number("depth", 2, 1e-9));
        } else if (shape == "sphere") {
            object.mesh = make_sphere(n.number("radius", 1, 1e-9), segments);
        } else if (shape == "cylinder") {
            object.mesh =
                make_cylinder(n.number("radius", 1, 1e-9), n.number("height", 2, 1e-9), segments);
        } else if (shape == "torus") {
            const double major = n.number("major_radius", 1, 1e-9);
            const double minor = n.number("minor_radius", 0.3, 1e-9, major);
            object.mesh = make_torus(major, minor, segments, std::max(3, segments / 2));
        } else {
            try {
                object.mesh = load_obj(resolve(n.required_string("file")));
            } catch (const Error& e) {
                n.fail(e.what());
            }
        }
        const Vec3 rotation = n.vec3("rotation", {0, 0, 0});
        const Transform xf =
            Transform::translate(n.vec3("position", {0, 0, 0})) *
            Transform::rotate({0, 0, 1}, rotation.z) * Transform::rotate({0, 1, 0}, rotation.y) *
            Transform::rotate({1, 0, 0}, rotation.x) * Transform::scale(n.scale3("scale"));
        transform(object.mesh, xf);
        if (n.has("uv_scale")) {
            const json& v = n.raw().at("uv_scale");
            if (v.is_number()) {
                object.uv.scale_u = object.uv.scale_v = n.number("uv_scale", 1, 1e-6, 1e6);
            } else if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number() &&
                       v[0].get<double>() > 0 && v[1].get<double>() > 0) {
                object.uv.scale_u = v[0].get<double>();
                object.uv.scale_v = v[1].get<double>();
            } else {
                n.fail("\"uv_scale\" must be a positive number or two");
            }
        }
        object.uv.rotation = n.number("uv_rotation", 0, -360, 360);
        object.surface = read_material(n.child("material"));
        return object;
    }

    void read_light(const Node& n, Scene& scene) const {
        const std::string type = n.required_string("type");
        if (type == "point") {
            n.allow({"type", "position", "intensity"});
            scene.add_light(std::make_shared<PointLight>(n.vec3("position", {0, 4, 0}),
                                                         n.rgb("intensity", {10, 10, 10})));
        } else if (type == "directional") {
            n.allow({"type", "direction", "irradiance"});
            const Vec3 d = n.vec3("direction", {0, 1, 0});
            if (length(d) == 0) n.fail("\"direction\" must not be zero");
            scene.add_light(std::make_shared<DirectionalLight>(d, n.rgb("irradiance", {1, 1, 1})));
        } else if (type == "sphere") {
            n.allow({"type", "center", "radius", "radiance"});
            scene.add_light(std::make_shared<SphereLight>(n.vec3("center", {0, 4, 0}),
                                                          n.number("radius", 0.5, 1e-9),
                                                          n.rgb("radiance", {10, 10, 10})));
        } else if (type == "environment") {
            n.allow({"type", "file", "sky", "scale", "rotation"});
            const double scale = n.number("scale", 1, 0);
            const double rotation = n.number("rotation", 0, -360, 360);
            if (n.has("file") == n.has("sky")) n.fail("give either \"file\" or \"sky\"");
            std::shared_ptr<const EnvironmentMap> map;
            if (n.has("file")) {
                try {
                    map = std::make_shared<const EnvironmentMap>(EnvironmentMap::from_file(
                        resolve(n.required_string("file")), scale, rotation));
                } catch (const Cancelled&) {
                    throw;
                } catch (const Error& e) {
                    n.fail(e.what());
                }
            } else {
                const Node sky = n.child("sky");
                sky.allow({"sun_elevation", "sun_azimuth", "width"});
                const double elevation = radians(sky.number("sun_elevation", 35, -90, 90));
                const double azimuth = radians(sky.number("sun_azimuth", 45, -360, 360));
                const int width = sky.integer("width", 1024, 16, 16384);
                const Vec3 sun = {std::cos(elevation) * std::cos(azimuth), std::sin(elevation),
                                  std::cos(elevation) * std::sin(azimuth)};
                try {
                    map = std::make_shared<const EnvironmentMap>(
                        EnvironmentMap::make_sky(width, width / 2, sun), scale, rotation);
                } catch (const Error& e) {
                    n.fail(e.what());
                }
            }
            try {
                scene.add_light(std::make_shared<EnvironmentLight>(map));
            } catch (const Error& e) {
                n.fail(e.what());
            }
        } else {
            n.fail(fmt::format(
                "unknown light type \"{}\" (point, directional, sphere, environment)", type));
        }
    }

    std::string m_name;
    std::filesystem::path m_base;
    const LoadOptions& m_options;
    std::map<std::string, std::shared_ptr<const Material>> m_materials;
    int m_btf_objects = 0;
};

}  // namespace

LoadedScene parse_scene(const std::string& text, const std::string& name,
                        const std::filesystem::path& base, const LoadOptions& options) {
    json root;
    try {
        root = json::parse(text);
    } catch (const json::parse_error& e) {
        throw Error(fmt::format("{}: not valid JSON: byte {}: {}", name, e.byte, e.what()));
    } catch (const json::exception& e) {  // e.g. a number beyond double's range
        throw Error(fmt::format("{}: not valid JSON: {}", name, e.what()));
    }
    return SceneReader(name, base, options).read(root);
}

LoadedScene load_scene(const std::filesystem::path& path, const LoadOptions& options) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path.string() + ": cannot open the scene file");
    std::stringstream text;
    text << in.rdbuf();
    return parse_scene(text.str(), path.string(), path.parent_path(), options);
}

RenderSetup apply_overrides(LoadedScene& loaded, const RenderOverrides& o) {
    RenderOptions options = loaded.settings.options;
    const std::string integrator = o.integrator.empty() ? loaded.settings.integrator : o.integrator;
    if (integrator == "direct") {
        if (o.max_depth > 0) fail("max-depth applies to the path integrator");
        options.integrator.max_depth = 1;
    } else if (integrator == "path") {
        if (loaded.settings.integrator != "path") options.integrator.max_depth = 8;
        if (o.max_depth > 0) options.integrator.max_depth = o.max_depth;
    } else {
        fail("integrator '{}': expected path or direct", integrator);
    }
    if (o.spp >= 0) options.spp = o.spp;
    if (o.time_limit >= 0) options.time_limit = o.time_limit;
    if (o.spp == 0 && options.time_limit <= 0) fail("0 samples per pixel needs a time limit");
    if (o.seed >= 0) options.seed = uint64_t(o.seed);
    if (!o.filter.empty()) options.integrator.filter = parse_filter(o.filter, "filter");
    if (o.width != 0 || o.height != 0) {
        if (o.width <= 0 || o.height <= 0 || o.width > 16384 || o.height > 16384)
            fail("image size {} × {}: width and height must be 1 to 16384", o.width, o.height);
        loaded.scene.camera.width = o.width;
        loaded.scene.camera.height = o.height;
    }
    options.aovs = o.aovs;
    return {options, std::isnan(o.exposure) ? loaded.settings.exposure : o.exposure};
}

}  // namespace btf::render
