// SPDX-License-Identifier: MIT
#include "btf/bsvtf/sim.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <fstream>
#include <list>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "btf/bsvtf/cache.h"
#include "btf/bsvtf/evaluator.h"
#include "btf/bsvtf/file.h"
#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/quality/render_compare.h"
#include "btf/render/scene_file.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/parallel.h"

namespace btf::bsvtf {

namespace {

constexpr double kPi = 3.14159265358979323846;

Vec3 vec3(const nlohmann::json& j, const std::string& what) {
    if (!j.is_array() || j.size() != 3) fail("{} must be three numbers", what);
    return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

// One material: its tiles as the server holds them, and what the client has received.
struct SimMaterialState {
    const factor::Model* model = nullptr;
    Pyramid pyramid;
    EncodedPyramid encoded;
    std::unique_ptr<Evaluator> evaluator;
    std::vector<float> energy;     // per tile: mean square of its texels (‖T‖² / texels)
    std::vector<uint64_t> u_size;  // per group: bytes of the U packet
    std::vector<bool> u_received;
};

// The client's store of decoded tiles, least recently used evicted first (never a tile the
// cache holds).
class Store {
  public:
    explicit Store(uint64_t capacity) : m_capacity(capacity) {}
    static uint64_t key(int material, size_t index) { return (uint64_t(material) << 40) | index; }
    bool has(uint64_t k) const { return m_entries.count(k) != 0; }
    const uint16_t* data(uint64_t k) const {
        const auto it = m_entries.find(k);
        return it == m_entries.end() ? nullptr : it->second.data.data();
    }
    void touch(uint64_t k) {
        const auto it = m_entries.find(k);
        if (it == m_entries.end()) return;
        m_order.splice(m_order.end(), m_order, it->second.position);
    }
    template <typename Pinned>
    void put(uint64_t k, std::vector<uint16_t> data, Pinned&& pinned) {
        if (has(k)) return;
        m_bytes += data.size() * 2;
        m_order.push_back(k);
        m_entries[k] = {std::move(data), std::prev(m_order.end())};
        for (auto it = m_order.begin(); m_bytes > m_capacity && it != m_order.end();) {
            if (*it == k || pinned(*it)) {
                ++it;
                continue;
            }
            m_bytes -= m_entries[*it].data.size() * 2;
            m_entries.erase(*it);
            it = m_order.erase(it);
        }
    }

  private:
    struct Entry {
        std::vector<uint16_t> data;
        std::list<uint64_t>::iterator position;
    };
    uint64_t m_capacity, m_bytes = 0;
    std::unordered_map<uint64_t, Entry> m_entries;
    std::list<uint64_t> m_order;
};

struct Request {
    bool u = false;  // a U packet (index = group) or a tile (index = tile index)
    int material = 0;
    size_t index = 0;
    uint64_t bytes = 0;
};

// What one pixel shows: the material, where, and the level it needs.
struct PixelHit {
    render::Hit hit;
    int material = -1;  // index into the simulator's materials; -1: not a BTF object or a miss
    int level = 0;
};

class Simulator {
  public:
    Simulator(const std::filesystem::path& scene_file, const SimOptions& options,
              Progress& progress)
        : m_options(options) {
        m_loaded = render::load_scene(scene_file);
        render::Scene& scene = m_loaded.scene;
        if (options.width > 0) scene.camera.width = options.width;
        if (options.height > 0) scene.camera.height = options.height;
        for (const auto& light : scene.lights())
            if (light->sample({0, 0, 0}, 0.5, 0.5).delta) m_delta_lights.push_back(light.get());
        if (m_delta_lights.empty())
            fail("{}: bsvtf-sim shades with point and directional lights; the scene has none",
                 scene_file.string());
        // Materials: one per distinct fmf material of the scene's BTF objects.
        std::map<const Material*, int> index;
        m_object_material.assign(scene.objects().size(), -1);
        for (size_t o = 0; o < scene.objects().size(); ++o) {
            const auto* btf =
                dynamic_cast<const render::BtfSurface*>(scene.objects()[o].surface.get());
            if (!btf) continue;
            const auto* fmf = dynamic_cast<const factor::FactorMaterial*>(&btf->material());
            if (!fmf || fmf->model().groups.size() != 1 || fmf->model().clusters != 1 ||
                fmf->model().levels != 1)
                fail("{}: object '{}': bsvtf-sim needs fmf packages as BTF materials",
                     scene_file.string(), scene.objects()[o].name);
            auto [it, added] = index.emplace(&btf->material(), int(m_materials.size()));
            if (added) {
                try {
                    prepare(*fmf, progress);
                } catch (const Cancelled&) {
                    throw;
                } catch (const Error& e) {
                    fail("{}: object '{}': {}", scene_file.string(), scene.objects()[o].name,
                         e.what());
                }
            }
            m_object_material[o] = it->second;
        }
        if (m_materials.empty()) fail("{}: the scene has no BTF object", scene_file.string());
        std::vector<const TileLayout*> layouts;
        std::vector<const std::vector<float>*> weights;
        for (const auto& m : m_materials) {
            layouts.push_back(&m->pyramid);
            weights.push_back(&m->pyramid.weights());
        }
        const int per_side = options.cache / options.geometry.stride();
        m_report.capacity = per_side * per_side;
        m_report.cache_bytes =
            uint64_t(m_report.capacity) * uint64_t(options.geometry.values()) * 2;
        m_cache = std::make_unique<TileCache>(layouts, weights, m_report.capacity);
        m_votes = std::make_unique<Votes>(layouts);
        m_store = std::make_unique<Store>(options.store_bytes);
        m_report.width = scene.camera.width;
        m_report.height = scene.camera.height;
    }

    SimReport run(const CameraPath& path, Progress& progress, const FrameCallback& on_frame) {
        progress.begin("simulating frames", uint64_t(path.frames));
        const double frame_bytes =
            m_options.bandwidth > 0 ? m_options.bandwidth / 8 / m_options.fps : 0;
        for (int f = 0; f < path.frames; ++f) {
            const CameraPose pose = path.at(f);
            m_loaded.scene.camera.position = pose.position;
            m_loaded.scene.camera.look_at = pose.look_at;
            SimFrame frame;
            frame.frame = f;
            frame.time = f / m_options.fps;
            feedback();
            if (frame_bytes > 0) {
                m_budget += frame_bytes;
                request();
                deliver();
                operate(frame);
            } else {
                // Unlimited link: request, receive and operate until the cache settles.
                for (int round = 0; round < 64; ++round) {
                    const int before = frame.adds + frame.swaps;
                    request();
                    m_budget = INFINITY;
                    const bool received = deliver();
                    m_budget = 0;
                    operate(frame);
                    if (frame.adds + frame.swaps == before && !received) break;
                }
            }
            frame.bytes = m_received;
            frame.tile_bytes = m_received_tiles;
            frame.resident = m_cache->size();
            frame.pending = int(m_queue.size());
            Image rendered, reference;
            render_frames(rendered, reference);
            const quality::RenderComparison c =
                quality::compare_displays(quality::tone_map(rendered, m_loaded.settings.exposure),
                                          quality::tone_map(reference, m_loaded.settings.exposure));
            frame.ssim = c.ssim;
            frame.psnr = c.psnr;
            frame.de2000 = c.de2000_mean;
            m_report.frames.push_back(frame);
            if (on_frame) on_frame(frame, rendered, reference, m_loaded.settings.exposure);
            progress.advance();
        }
        progress.finish();
        return m_report;
    }

  private:
    void prepare(const factor::FactorMaterial& fmf, Progress& progress) {
        const auto start = std::chrono::steady_clock::now();
        auto m = std::make_unique<SimMaterialState>();
        m->model = &fmf.model();
        m->pyramid = Pyramid::build(fmf.model(), m_options.geometry, progress);
        m->encoded =
            encode_pyramid(m->pyramid, step_for(m->pyramid, m_options.tile_error), 9, progress);
        m->evaluator = std::make_unique<Evaluator>(fmf.model(), m->pyramid);
        const TileGeometry& g = m->pyramid.geometry();
        m->energy.resize(m->pyramid.tile_count());
        for (size_t t = 0; t < m->pyramid.tile_count(); ++t)
            m->energy[t] =
                float(m->pyramid.squared_sum(m->pyramid.id(t)) / (double(g.tile) * g.tile));
        SimMaterial info;
        const factor::Model& model = fmf.model();
        int components = 0;
        uint64_t rows = 0;
        // The U packets as make_bsvtf writes them: half floats when that loses nothing.
        const uint64_t u_bytes = angular_factors_are_half(model) ? 2 : 4;
        for (const Group& group : m->pyramid.groups()) {
            const int64_t r = model.block_rows(0, 0);
            m->u_size.push_back(uint64_t(r) * uint64_t(group.count) * u_bytes);
            info.u_bytes += m->u_size.back();
            components += group.count;
            rows = uint64_t(r);
        }
        m->u_received.assign(m->pyramid.groups().size(), false);
        info.width = model.width;
        info.height = model.height;
        info.components = components;
        info.levels = m->pyramid.levels();
        info.tiles = m->pyramid.tile_count();
        info.raw_tile_bytes = m->encoded.raw_bytes;
        info.encoded_tile_bytes = m->encoded.encoded_bytes;
        info.fmf_bytes =
            (uint64_t(model.width) * uint64_t(model.height) + rows) * uint64_t(components) * 2;
        info.codec_error = m->encoded.relative_rms_error;
        info.prep_seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        m_report.materials.push_back(info);
        m_materials.push_back(std::move(m));
    }

    // The material, texture position and needed level of the pixel at (x, y) (pixel units of a
    // w × h image); `step` is the pixel spacing of the full-resolution frame in these units.
    PixelHit trace(double x, double y, double step) const {
        const render::Scene& scene = m_loaded.scene;
        PixelHit p;
        p.hit = scene.intersect(scene.camera.ray(x, y));
        if (p.hit.object < 0) return p;
        p.material = m_object_material[size_t(p.hit.object)];
        if (p.material < 0) return p;
        const Pyramid& pyramid = m_materials[size_t(p.material)]->pyramid;
        // Equation 1: the footprint of a full-resolution pixel in level-0 texels, from the
        // texture positions one pixel to the right and one below (or to the left / above).
        double footprint = 0;
        for (const auto [dx, dy] : {std::pair{1.0, 0.0}, std::pair{0.0, 1.0}}) {
            for (const double sign : {1.0, -1.0}) {
                const render::Hit n =
                    scene.intersect(scene.camera.ray(x + sign * dx * step, y + sign * dy * step));
                if (n.object != p.hit.object) continue;
                double du = n.uv.u - p.hit.uv.u, dv = n.uv.v - p.hit.uv.v;
                du -= std::round(du);  // across the wrap of the texture
                dv -= std::round(dv);
                footprint =
                    std::max(footprint, std::hypot(du * pyramid.width(), dv * pyramid.height()));
                break;
            }
        }
        p.level = footprint > 1
                      ? std::min(pyramid.levels() - 1, int(std::floor(std::log2(footprint))))
                      : 0;
        return p;
    }

    void feedback() {
        const render::Camera& camera = m_loaded.scene.camera;
        const int d = std::max(1, m_options.feedback_divisor);
        const int w = std::max(1, camera.width / d), h = std::max(1, camera.height / d);
        std::vector<PixelHit> hits(size_t(w) * size_t(h));
        parallel_for(0, h, [&](int64_t y) {
            for (int x = 0; x < w; ++x)
                hits[size_t(y) * size_t(w) + size_t(x)] =
                    trace((x + 0.5) * d, (double(y) + 0.5) * d, 1.0);
        });
        m_votes->clear();
        for (const PixelHit& p : hits)
            if (p.material >= 0) m_votes->add(p.material, p.level, p.hit.uv.u, p.hit.uv.v);
    }

    bool in_store(const TileKey& t) const {
        return m_store->has(
            Store::key(t.material, m_materials[size_t(t.material)]->pyramid.index(t.id)));
    }

    // Chooses what to ask the server for, by priority, keeping about two frames of data (or,
    // unlimited, everything useful now) in flight.
    void request() {
        struct Candidate {
            double priority;
            Request request;
        };
        std::vector<Candidate> candidates;
        const auto requested = [&](const Request& r) {
            return m_requested.count({r.u, r.material, r.index}) != 0;
        };
        const std::vector<TileKey> resident = m_cache->tiles();
        for (int mi = 0; mi < int(m_materials.size()); ++mi) {
            const SimMaterialState& m = *m_materials[size_t(mi)];
            const Pyramid& p = m.pyramid;
            const int top = p.levels() - 1;
            for (int g = 0; g < int(p.groups().size()); ++g) {
                for (int y = 0; y < p.tiles_y(top); ++y)
                    for (int x = 0; x < p.tiles_x(top); ++x) {
                        const TileId t{g, top, x, y};
                        const double v = (*m_votes)(mi, t);
                        if (v > 0 && !in_store({mi, t})) {
                            const Request r{false, mi, p.index(t),
                                            m.encoded.payloads[p.index(t)].size()};
                            if (!requested(r)) candidates.push_back({v * m.energy[p.index(t)], r});
                        }
                    }
                if (m.u_received[size_t(g)]) continue;
                // §6: U_g is worth what the group's received tiles on screen would show with it.
                double u_priority = 0;
                for (const TileKey& t : resident)
                    if (t.material == mi && t.id.group == g && in_store(t))
                        u_priority += (*m_votes)(mi, t.id) * m.energy[p.index(t.id)];
                if (u_priority > 0) {
                    const Request r{true, mi, size_t(g), m.u_size[size_t(g)]};
                    if (!requested(r)) candidates.push_back({u_priority, r});
                }
            }
        }
        m_cache->for_each_add_candidate(*m_votes, [&](const TileKey& t, double priority) {
            const SimMaterialState& m = *m_materials[size_t(t.material)];
            const size_t i = m.pyramid.index(t.id);
            // Decodable once it arrives: its parent is resident, so in the store unless it is a
            // coarsest tile still on its way.
            if (in_store(t) || !in_store({t.material, m.pyramid.parent(t.id)})) return;
            const Request r{false, t.material, i, m.encoded.payloads[i].size()};
            if (!requested(r)) candidates.push_back({priority, r});
        });
        for (const Request& r : m_wanted) {
            const SimMaterialState& m = *m_materials[size_t(r.material)];
            if (!in_store({r.material, m.pyramid.id(r.index)}) && !requested(r))
                candidates.push_back({INFINITY, r});
        }
        m_wanted.clear();
        std::sort(candidates.begin(), candidates.end(),
                  [](const Candidate& a, const Candidate& b) { return a.priority > b.priority; });
        const double frame_bytes = m_options.bandwidth / 8 / m_options.fps;
        for (const Candidate& c : candidates) {
            if (m_options.bandwidth > 0 && double(m_queued) >= 2 * frame_bytes) break;
            // The same tile can be a candidate twice (an add and a swap's ancestor).
            if (!m_requested.insert({c.request.u, c.request.material, c.request.index}).second)
                continue;
            m_queue.push_back(c.request);
            m_queued += c.request.bytes;
        }
    }

    // Sends what the link carries this frame; returns whether anything arrived.
    bool deliver() {
        bool any = false;
        while (!m_queue.empty()) {
            Request& r = m_queue.front();
            const double left = double(r.bytes - m_sent_of_head);
            if (m_budget < left) {
                m_sent_of_head += uint64_t(m_budget);
                m_budget = 0;
                break;
            }
            m_budget -= left;
            m_sent_of_head = 0;
            m_received += r.bytes;
            m_queued -= r.bytes;
            receive(r);
            m_requested.erase({r.u, r.material, r.index});
            m_queue.pop_front();
            any = true;
        }
        if (m_queue.empty()) m_budget = std::min(m_budget, 0.0);  // no credit on an idle link
        return any;
    }

    void receive(const Request& r) {
        SimMaterialState& m = *m_materials[size_t(r.material)];
        if (r.u) {
            m.u_received[r.index] = true;
            return;
        }
        m_received_tiles += r.bytes;
        const TileId id = m.pyramid.id(r.index);
        const TileGeometry& g = m.pyramid.geometry();
        std::vector<float> prediction;
        if (m.pyramid.has_parent(id)) {
            const uint16_t* parent =
                m_store->data(Store::key(r.material, m.pyramid.index(m.pyramid.parent(id))));
            if (!parent) return;  // its parent left the store meanwhile: asked for again later
            prediction = predict_child({parent, size_t(g.values())}, g, id);
        }
        std::vector<uint16_t> data(size_t(g.values()));
        decode_tile(m.encoded.payloads[r.index], prediction, g, data);
        m_store->put(Store::key(r.material, r.index), std::move(data), [&](uint64_t k) {
            const int mi = int(k >> 40);
            return m_cache->resident(
                {mi, m_materials[size_t(mi)]->pyramid.id(k & ((uint64_t(1) << 40) - 1))});
        });
    }

    // The decision rule of §5.2 with what the store holds.
    void operate(SimFrame& frame) {
        const TileCache::Decision d = m_cache->decide(
            *m_votes, [&](const TileKey& t) { return in_store(t); }, m_options.operations);
        for (const TileCache::Operation& op : d.operations)
            (op.kind == TileCache::Operation::Kind::kAdd ? frame.adds : frame.swaps) += 1;
        if (d.wanted) {
            // The ancestor to bring back left the store: ask for it again.
            const Pyramid& p = m_materials[size_t(d.wanted->material)]->pyramid;
            const size_t i = p.index(d.wanted->id);
            m_wanted.push_back(
                {false, d.wanted->material, i,
                 m_materials[size_t(d.wanted->material)]->encoded.payloads[i].size()});
        }
    }

    Rgb shade(const PixelHit& p, bool reference, const render::Ray& ray) const {
        const render::Scene& scene = m_loaded.scene;
        const render::SceneObject& object = scene.objects()[size_t(p.hit.object)];
        Vec3 wo = p.hit.to_local(-ray.direction);
        if (wo.z < 1e-4) wo = normalize(Vec3{wo.x, wo.y, 1e-4});
        Rgb sum;
        Evaluator::Angular angular;
        // The simulator's picture is the filtered value (what a viewer shows), not a sample of it.
        const render::Vertex vertex =
            object.surface->vertex(p.hit.uv, wo, Filter::kDeterministic, 0);
        for (const render::Light* light : m_delta_lights) {
            const render::LightDirection ld = light->sample(p.hit.position, 0.5, 0.5);
            if (dot(ld.wi, p.hit.geometric_normal) <= 0) continue;
            const Vec3 wi = p.hit.to_local(ld.wi);
            if (wi.z <= 0) continue;
            const double reach = std::isfinite(ld.distance) ? ld.distance * (1 - 1e-4) : INFINITY;
            if (scene.occluded(scene.spawn(p.hit, ld.wi), reach)) continue;
            Rgb f;
            if (p.material < 0) {
                f = object.surface->eval(vertex, wi);
            } else {
                const SimMaterialState& m = *m_materials[size_t(p.material)];
                m.evaluator->angular(wi, wo, angular);
                f = m.evaluator->value(angular, [&](int g) -> std::optional<std::array<float, 4>> {
                    if (reference) return m.pyramid.sample(g, p.level, p.hit.uv);
                    return sample_cache(p, g);
                });
                f = {std::max(f.r, 0.0f), std::max(f.g, 0.0f), std::max(f.b, 0.0f)};
            }
            sum +=
                Rgb{f.r * ld.radiance.r, f.g * ld.radiance.g, f.b * ld.radiance.b} * float(1 / kPi);
        }
        return sum;
    }

    std::optional<std::array<float, 4>> sample_cache(const PixelHit& p, int g) const {
        const SimMaterialState& m = *m_materials[size_t(p.material)];
        if (!m.u_received[size_t(g)]) return std::nullopt;
        return sample_cached(
            *m_cache, m.pyramid, p.material, g, p.level, p.hit.uv, [&](const TileKey& t) {
                return m_store->data(Store::key(t.material, m.pyramid.index(t.id)));
            });
    }

    void render_frames(Image& rendered, Image& reference) {
        const render::Camera& camera = m_loaded.scene.camera;
        rendered = Image(camera.width, camera.height, 3);
        reference = Image(camera.width, camera.height, 3);
        parallel_for(0, camera.height, [&](int64_t y) {
            for (int x = 0; x < camera.width; ++x) {
                const PixelHit p = trace(x + 0.5, double(y) + 0.5, 1.0);
                if (p.hit.object < 0) continue;
                const render::Ray ray = m_loaded.scene.camera.ray(x + 0.5, double(y) + 0.5);
                rendered.set_rgb(x, int(y), shade(p, false, ray));
                reference.set_rgb(x, int(y), shade(p, true, ray));
            }
        });
        for (const TileKey& t : m_cache->tiles())
            m_store->touch(
                Store::key(t.material, m_materials[size_t(t.material)]->pyramid.index(t.id)));
    }

    SimOptions m_options;
    render::LoadedScene m_loaded;
    std::vector<const render::Light*> m_delta_lights;
    std::vector<int> m_object_material;
    std::vector<std::unique_ptr<SimMaterialState>> m_materials;
    std::unique_ptr<TileCache> m_cache;
    std::unique_ptr<Votes> m_votes;
    std::unique_ptr<Store> m_store;
    std::deque<Request> m_queue;
    std::set<std::tuple<bool, int, size_t>> m_requested;
    std::vector<Request> m_wanted;
    uint64_t m_queued = 0, m_sent_of_head = 0, m_received = 0, m_received_tiles = 0;
    double m_budget = 0;
    SimReport m_report;
};

}  // namespace

CameraPose CameraPath::at(int frame) const {
    if (keys.empty()) return {};
    if (frame <= keys.front().first) return keys.front().second;
    for (size_t i = 1; i < keys.size(); ++i)
        if (frame <= keys[i].first) {
            const auto& [f0, a] = keys[i - 1];
            const auto& [f1, b] = keys[i];
            const double t = (frame - f0) / (f1 - f0);
            return {a.position + (b.position - a.position) * t,
                    a.look_at + (b.look_at - a.look_at) * t};
        }
    return keys.back().second;
}

CameraPath read_camera_path(const std::filesystem::path& file) {
    std::ifstream in(file);
    if (!in) fail("{}: cannot open the camera path", file.string());
    try {
        const nlohmann::json j = nlohmann::json::parse(in);
        CameraPath path;
        path.frames = j.at("frames").get<int>();
        if (path.frames < 1 || path.frames > 100000) fail("frames {} is out of range", path.frames);
        double previous = -INFINITY;
        for (const auto& k : j.at("keys")) {
            const double frame = k.at("frame").get<double>();
            if (!(frame > previous)) fail("key frames must increase");
            previous = frame;
            path.keys.push_back(
                {frame, {vec3(k.at("position"), "position"), vec3(k.at("look_at"), "look_at")}});
        }
        if (path.keys.empty()) fail("no keys");
        return path;
    } catch (const Cancelled&) {
        throw;
    } catch (const std::exception& e) {
        fail("{}: bad camera path: {}", file.string(), e.what());
    }
}

SimReport simulate(const std::filesystem::path& scene, const CameraPath& path,
                   const SimOptions& options, Progress& progress, const FrameCallback& on_frame) {
    Simulator sim(scene, options, progress);
    return sim.run(path, progress, on_frame);
}

}  // namespace btf::bsvtf
