// SPDX-License-Identifier: MIT
#include "btf/synth/synth.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>

#include "btf/synth/microfacet.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::synth {

namespace {

struct V3 {
    float x, y, z;
};

V3 to_v3(const Vec3& v) {
    return {float(v.x), float(v.y), float(v.z)};
}

// A direction in a texel's frame whose z fell at or below the horizon (a view ray meets a
// facet that, after interpolation, leans slightly away): keep it just above, same azimuth.
V3 lift_above_horizon(V3 w, float min_z) {
    if (w.z >= min_z) return w;
    const float xy = std::sqrt(w.x * w.x + w.y * w.y);
    const float s = xy > 0 ? std::sqrt(1 - min_z * min_z) / xy : 0.0f;
    return {w.x * s, w.y * s, min_z};
}

float iso_lambda(float cos_theta, float alpha) {
    const float c2 = cos_theta * cos_theta;
    return 0.5f * (std::sqrt(1.0f + alpha * alpha * (1 - c2) / c2) - 1.0f);
}

constexpr float kMinCos = 0.02f;

// Views at the horizon (θ = 90°, allowed in direction files) are taken at 89°: the ray march
// through the height field needs a finite slope.
Vec3 above_horizon(const Vec3& w) {
    const double min_z = std::cos(radians(89.0));
    if (w.z >= min_z) return w;
    const double xy = std::hypot(w.x, w.y);
    const double s = std::sqrt(1 - min_z * min_z) / xy;
    return {w.x * s, w.y * s, min_z};
}

}  // namespace

// Orthonormal frame of each texel: z = normal of the height field, x = the material's tangent.
struct SynthSource::Frames {
    std::vector<V3> t, b, n;
    std::vector<V3> coat_n;  // empty without a coat
};

// The bilinear tap of the surface point an output texel sees: the texel (x0, y0) left-above
// it, wrapped into the period, and the weights toward the next texel in x and y.
struct Tap {
    uint16_t x0, y0;
    float tx, ty;
};
static_assert(kMaxSize <= 65536, "Tap stores texel coordinates in 16 bits");

// What a view direction needs per texel, independent of the light.
struct SynthSource::ViewData {
    bool identity = false;      // zenith view: output texel p sees texel p
    std::vector<Tap> taps;      // per output texel (empty for the identity)
    std::vector<V3> wo;         // view vector in the texel frame
    std::vector<float> lambda;  // Smith Λ(wo)
    std::vector<float> coat_cos, coat_lambda, coat_trans;  // coat: cos, Λ, 1 − Fresnel
    int64_t bytes() const {
        return int64_t(lambda.size() + coat_cos.size() + coat_lambda.size() + coat_trans.size()) *
                   4 +
               int64_t(wo.size()) * 12 + int64_t(taps.size()) * int64_t(sizeof(Tap));
    }
};

// What a light direction needs per texel, independent of the view.
struct SynthSource::LightData {
    std::vector<V3> wi;         // light vector in the texel frame
    std::vector<float> lambda;  // Smith Λ(wi)
    std::vector<float> direct;  // visibility (soft shadow); 0 where the texel faces away
    std::vector<float> bounce;  // irradiance reflected onto the texel by its neighbours
    std::vector<float> coat_cos, coat_lambda, coat_trans;
    int64_t bytes() const {
        return int64_t(lambda.size() + direct.size() + coat_cos.size() + coat_lambda.size() +
                       coat_trans.size()) *
                   4 +
               int64_t(bounce.size()) * 4 + int64_t(wi.size()) * 12;
    }
};

// Cache of per-view and per-light data with a memory budget and least-recently-used eviction.
// Each slot is computed once at a time (its compute mutex); readers take its data mutex only
// to copy the pointer. Lock order: compute(slot) → m_mutex → data(any slot); data mutexes are
// never held while taking another lock, so no cycle can form.
class SynthSource::Cache {
  public:
    Cache(int slots, int64_t budget)
        : m_slots(new Slot[size_t(slots)]), m_count(slots), m_budget(budget) {}

    template <typename Compute>
    std::shared_ptr<const void> get(int index, Compute&& compute) {
        Slot& slot = m_slots[index];
        if (auto p = load(slot)) return p;
        std::lock_guard<std::mutex> compute_lock(slot.compute);
        if (auto p = load(slot)) return p;
        int64_t bytes = 0;
        std::shared_ptr<const void> value;
        // Isolation: while this thread waits inside the nested parallel loops of compute(), it
        // must not pick up an outer task (another read_image) that could wait for this slot.
        tbb::this_task_arena::isolate([&] { value = compute(bytes); });
        {
            std::lock_guard<std::mutex> data_lock(slot.data);
            slot.value = value;
            slot.bytes = bytes;
            slot.stamp = ++m_clock;
        }
        std::lock_guard<std::mutex> lock(m_mutex);
        m_total += bytes;
        while (m_total > m_budget) {
            int victim = -1;
            uint64_t oldest = UINT64_MAX;
            for (int i = 0; i < m_count; ++i) {
                if (i == index) continue;
                std::lock_guard<std::mutex> data_lock(m_slots[i].data);
                if (m_slots[i].value && m_slots[i].stamp < oldest)
                    oldest = m_slots[i].stamp, victim = i;
            }
            if (victim < 0) break;
            std::lock_guard<std::mutex> data_lock(m_slots[victim].data);
            m_slots[victim].value.reset();
            m_total -= m_slots[victim].bytes;
            m_slots[victim].bytes = 0;
        }
        return value;
    }

  private:
    struct Slot {
        std::mutex compute, data;
        std::shared_ptr<const void> value;
        int64_t bytes = 0;
        uint64_t stamp = 0;
    };

    std::shared_ptr<const void> load(Slot& slot) {
        std::lock_guard<std::mutex> data_lock(slot.data);
        if (slot.value) slot.stamp = ++m_clock;
        return slot.value;
    }

    std::unique_ptr<Slot[]> m_slots;
    int m_count;
    int64_t m_budget;
    std::atomic<uint64_t> m_clock{0};
    std::mutex m_mutex;
    int64_t m_total = 0;
};

SynthSource::SynthSource(const std::string& preset, int size, Sampling sampling, uint64_t seed,
                         const SynthOptions& options)
    : m_preset(preset), m_seed(seed), m_sampling(std::move(sampling)) {
    check(m_sampling.num_views() > 0 && m_sampling.num_lights() > 0,
          "synthetic BTF '{}': the sampling has {} views and {} lights; both must be non-empty",
          preset, m_sampling.num_views(), m_sampling.num_lights());
    m_surface = make_surface(preset, size, seed);
    m_info.format = "synthetic";
    m_info.hdr = true;  // narrow highlights exceed 1
    m_info.note = fmt::format("preset '{}', seed {}, {}x{} texels, {} views x {} lights", preset,
                              seed, size, size, m_sampling.num_views(), m_sampling.num_lights());

    const Surface& s = m_surface;
    const int n = s.size;
    const size_t count = size_t(n) * n;
    m_frames = std::make_unique<Frames>();
    Frames& f = *m_frames;
    f.t.resize(count), f.b.resize(count), f.n.resize(count);
    if (s.coat) f.coat_n.resize(count);
    auto normal_of = [](const Field& h, int x, int y) {
        const double gx = 0.5 * (h.wrapped(x + 1, y) - h.wrapped(x - 1, y));
        const double gy = 0.5 * (h.wrapped(x, y + 1) - h.wrapped(x, y - 1));
        return normalize(Vec3{-gx, -gy, 1.0});
    };
    parallel_chunks(0, n, 8, [&](int64_t y0, int64_t y1) {
        for (int y = int(y0); y < int(y1); ++y)
            for (int x = 0; x < n; ++x) {
                const size_t i = size_t(y) * n + x;
                const Vec3 nn = normal_of(s.height, x, y);
                const Vec3 t0{std::cos(double(s.tangent[i])), std::sin(double(s.tangent[i])), 0};
                const Vec3 t = normalize(t0 - nn * dot(nn, t0));
                f.n[i] = to_v3(nn);
                f.t[i] = to_v3(t);
                f.b[i] = to_v3(cross(nn, t));
                if (s.coat) f.coat_n[i] = to_v3(normal_of(s.coat_height, x, y));
            }
    });
    m_sky = sky_visibility(s.height, 16);
    // Bounced light arrives with the colour of the mean bounce albedo and leaves with the
    // texel's own.
    double sum[3] = {0, 0, 0};
    for (const Rgb& c : s.bounce) sum[0] += c.r, sum[1] += c.g, sum[2] += c.b;
    const Rgb mean{float(sum[0] / count), float(sum[1] / count), float(sum[2] / count)};
    m_bounce_tint.resize(count);
    for (size_t i = 0; i < count; ++i) {
        const Rgb& a = s.bounce[i];
        m_bounce_tint[i] = {a.r * mean.r, a.g * mean.g, a.b * mean.b};
    }
    m_cache = std::make_unique<Cache>(m_sampling.num_views() + m_sampling.num_lights(),
                                      options.cache_bytes);
}

SynthSource::~SynthSource() = default;

std::shared_ptr<const SynthSource::ViewData> SynthSource::view_data(int view) const {
    return std::static_pointer_cast<const ViewData>(m_cache->get(view, [&](int64_t& bytes) {
        auto data = compute_view(view);
        bytes = data->bytes();
        return std::shared_ptr<const void>(std::move(data));
    }));
}

std::shared_ptr<const SynthSource::LightData> SynthSource::light_data(int light) const {
    return std::static_pointer_cast<const LightData>(
        m_cache->get(m_sampling.num_views() + light, [&](int64_t& bytes) {
            auto data = compute_light(light);
            bytes = data->bytes();
            return std::shared_ptr<const void>(std::move(data));
        }));
}

std::shared_ptr<SynthSource::ViewData> SynthSource::compute_view(int view) const {
    const Surface& s = m_surface;
    const Frames& f = *m_frames;
    const int n = s.size;
    const size_t count = size_t(n) * n;
    const Vec3 wo = above_horizon(m_sampling.views.vector(view));
    auto d = std::make_shared<ViewData>();
    d->identity = std::hypot(wo.x, wo.y) < 1e-9;
    if (!d->identity) {
        std::vector<float> hit_x(count), hit_y(count);
        view_hits(s.height, wo, s.reference, hit_x.data(), hit_y.data());
        d->taps.resize(count);
        for (size_t i = 0; i < count; ++i) {
            const double fx = double(hit_x[i]) - 0.5, fy = double(hit_y[i]) - 0.5;
            const double x0 = std::floor(fx), y0 = std::floor(fy);
            d->taps[i] = {uint16_t(wrap_index(int(x0), n)), uint16_t(wrap_index(int(y0), n)),
                          float(fx - x0), float(fy - y0)};
        }
    }
    d->wo.resize(count), d->lambda.resize(count);
    if (s.coat)
        d->coat_cos.resize(count), d->coat_lambda.resize(count), d->coat_trans.resize(count);
    const V3 w = to_v3(wo);
    parallel_chunks(0, int64_t(count), 4096, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) {
            const V3 t = f.t[i], bt = f.b[i], nn = f.n[i];
            const V3 local = lift_above_horizon(
                {t.x * w.x + t.y * w.y + t.z * w.z, bt.x * w.x + bt.y * w.y + bt.z * w.z,
                 nn.x * w.x + nn.y * w.y + nn.z * w.z},
                kMinCos);
            d->wo[i] = local;
            d->lambda[i] = ggx_lambda(local.x, local.y, local.z, s.alpha_t[i], s.alpha_b[i]);
            if (s.coat) {
                const V3 c = f.coat_n[i];
                const float co = std::max(kMinCos, c.x * w.x + c.y * w.y + c.z * w.z);
                d->coat_cos[i] = co;
                d->coat_lambda[i] = iso_lambda(co, s.coat_alpha);
                d->coat_trans[i] = 1 - (s.coat_f0 + (1 - s.coat_f0) * schlick_weight(co));
            }
        }
    });
    return d;
}

std::shared_ptr<SynthSource::LightData> SynthSource::compute_light(int light) const {
    const Surface& s = m_surface;
    const Frames& f = *m_frames;
    const int n = s.size;
    const size_t count = size_t(n) * n;
    const Vec3 wi = m_sampling.lights.vector(light);
    auto d = std::make_shared<LightData>();
    d->wi.resize(count), d->lambda.resize(count), d->direct.resize(count);
    d->bounce.resize(count);
    if (s.coat)
        d->coat_cos.resize(count), d->coat_lambda.resize(count), d->coat_trans.resize(count);
    light_visibility(s.height, wi, s.light_size, d->direct.data());
    Field irradiance(n);
    const V3 w = to_v3(wi);
    parallel_chunks(0, int64_t(count), 4096, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) {
            const V3 t = f.t[i], bt = f.b[i], nn = f.n[i];
            const V3 local{t.x * w.x + t.y * w.y + t.z * w.z, bt.x * w.x + bt.y * w.y + bt.z * w.z,
                           nn.x * w.x + nn.y * w.y + nn.z * w.z};
            d->wi[i] = local;
            if (local.z > 0) {
                d->lambda[i] = ggx_lambda(local.x, local.y, local.z, s.alpha_t[i], s.alpha_b[i]);
            } else {
                d->direct[i] = 0;  // facing away from the light
                d->lambda[i] = 0;
            }
            irradiance.values()[i] = d->direct[i] * std::max(0.0f, local.z);
            if (s.coat) {
                const V3 c = f.coat_n[i];
                const float ci = c.x * w.x + c.y * w.y + c.z * w.z;
                d->coat_cos[i] = ci;
                d->coat_lambda[i] = ci > 0 ? iso_lambda(ci, s.coat_alpha) : 0.0f;
                d->coat_trans[i] =
                    1 - (s.coat_f0 + (1 - s.coat_f0) * schlick_weight(std::max(0.0f, ci)));
            }
        }
    });
    // One diffuse bounce: a texel sees neighbouring surfaces over the part of its hemisphere
    // that is not open sky; they shine with the locally averaged direct irradiance times the
    // mean bounce albedo.
    const Field near = blur(irradiance, s.bounce_radius, 2);
    parallel_chunks(0, int64_t(count), 4096, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) {
            d->bounce[i] = (1 - m_sky.values()[i]) * near.values()[i];
        }
    });
    return d;
}

void SynthSource::read_image(int view, int light, Image& out) const {
    check(
        view >= 0 && view < m_sampling.num_views() && light >= 0 && light < m_sampling.num_lights(),
        "synthetic BTF '{}': image (view {}, light {}) is outside the sampling ({} views, {} "
        "lights)",
        m_preset, view, light, m_sampling.num_views(), m_sampling.num_lights());
    const auto vd = view_data(view);
    const auto ld = light_data(light);
    const Surface& s = m_surface;
    const int n = s.size;
    const size_t count = size_t(n) * n;

    // Per-image constants: the half vector's length and the Fresnel angle do not depend on the
    // texel frame (both vectors rotate with it).
    const Vec3 wi_m = m_sampling.lights.vector(light),
               wo_m = above_horizon(m_sampling.views.vector(view));
    const float sum_len = float(std::max(length(wi_m + wo_m), 1e-6));
    const float inv_len = 1.0f / sum_len;
    const float fresnel_w = schlick_weight(0.5f * sum_len);
    const bool sheen = !s.sheen.empty();
    const float coat_fresnel = s.coat_f0 + (1 - s.coat_f0) * fresnel_w;
    const float coat_a2 = s.coat_alpha * s.coat_alpha;

    out.reshape(n, n, 3);
    std::unique_ptr<float[]> shaded;  // every element is written before it is read
    float* target = out.data();
    if (!vd->identity) {
        shaded = std::make_unique_for_overwrite<float[]>(count * 3);
        target = shaded.get();
    }
    parallel_chunks(0, int64_t(count), 4096, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) {
            const Rgb& tint = m_bounce_tint[i];
            const float incoming = ld->bounce[i];
            float r = tint.r * incoming, g = tint.g * incoming, bl = tint.b * incoming;
            const float vis = ld->direct[i];
            if (vis > 0) {
                const V3 wi = ld->wi[i], wo = vd->wo[i];
                const float hx = (wi.x + wo.x) * inv_len, hy = (wi.y + wo.y) * inv_len;
                const float hz = (wi.z + wo.z) * inv_len;
                float spec = 0;
                if (hz > 0) {
                    const float dist = ggx_d(hx, hy, hz, s.alpha_t[i], s.alpha_b[i]);
                    const float g2 = 1.0f / (1.0f + ld->lambda[i] + vd->lambda[i]);
                    // π·f·cos θi: the cos θi cancels the 1/(4 cos θi cos θo) of the BRDF.
                    spec = kPiF * dist * g2 / (4.0f * wo.z);
                }
                const Rgb& f0 = s.specular[i];
                const Rgb& a = s.albedo[i];
                float dr = a.r * wi.z + spec * (f0.r + (1 - f0.r) * fresnel_w);
                float dg = a.g * wi.z + spec * (f0.g + (1 - f0.g) * fresnel_w);
                float db = a.b * wi.z + spec * (f0.b + (1 - f0.b) * fresnel_w);
                if (sheen) {
                    const float k = kPiF * charlie_d(hz, s.sheen_roughness) *
                                    sheen_visibility(wi.z, wo.z) * wi.z;
                    const Rgb& c = s.sheen[i];
                    dr += k * c.r, dg += k * c.g, db += k * c.b;
                }
                if (s.coat) {
                    const float ci = ld->coat_cos[i];
                    const float trans = ld->coat_trans[i] * vd->coat_trans[i];
                    dr *= trans, dg *= trans, db *= trans;
                    if (ci > 0) {
                        const float co = vd->coat_cos[i];
                        // co is clamped to kMinCos, so (ci + co)·inv_len can exceed 1 at grazing
                        // angles, where t would reach 0 and D explode (values of 10⁶ seen).
                        const float ch = std::min(1.0f, (ci + co) * inv_len);
                        const float t = ch * ch * (coat_a2 - 1) + 1;
                        const float dist = coat_a2 / (kPiF * t * t);
                        const float g2 = 1.0f / (1.0f + ld->coat_lambda[i] + vd->coat_lambda[i]);
                        const float c = kPiF * dist * g2 * coat_fresnel / (4.0f * co);
                        dr += c, dg += c, db += c;
                    }
                }
                r += vis * dr, g += vis * dg, bl += vis * db;
            }
            float* p = target + i * 3;
            p[0] = r, p[1] = g, p[2] = bl;
        }
    });
    if (vd->identity) return;

    // Resample the shaded surface at the points the viewer sees (bilinear, wrapped).
    parallel_chunks(0, int64_t(count), 4096, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) {
            const Tap tap = vd->taps[i];
            const float tx = tap.tx, ty = tap.ty;
            const int x0 = tap.x0, y0 = tap.y0;
            const int x1 = x0 + 1 == n ? 0 : x0 + 1, y1 = y0 + 1 == n ? 0 : y0 + 1;
            const float* p00 = &shaded[(size_t(y0) * n + x0) * 3];
            const float* p10 = &shaded[(size_t(y0) * n + x1) * 3];
            const float* p01 = &shaded[(size_t(y1) * n + x0) * 3];
            const float* p11 = &shaded[(size_t(y1) * n + x1) * 3];
            float* o = out.data() + i * 3;
            for (int c = 0; c < 3; ++c) {
                const float top = p00[c] + tx * (p10[c] - p00[c]);
                const float bottom = p01[c] + tx * (p11[c] - p01[c]);
                o[c] = top + ty * (bottom - top);
            }
        }
    });
}

std::unique_ptr<BtfSource> make(const std::string& preset, int size, const Sampling& sampling,
                                uint64_t seed, const SynthOptions& options) {
    return std::make_unique<SynthSource>(preset, size, sampling, seed, options);
}

}  // namespace btf::synth
