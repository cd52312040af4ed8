// FactorMaterial: the fast evaluator of the linear factor model.
//
// A query touches ≤ 3 views × ≤ 3 lights (angular weights w_p) and 4 texels (bilinear weights
// s_t). Because the model is linear in both factors,
//     Σ_p Σ_t w_p s_t (mean(p) + a(p) · b(t)) = Σ_p w_p mean(p) + (Σ_p w_p a(p)) · (Σ_t s_t b(t))
// within one block, so a query costs 9 + 4 vector accumulations and one dot product of length K
// per block and channel instead of 36 reconstructions. Component vectors are padded to a
// multiple of 8 floats and processed with compiler vector extensions (8 lanes: one AVX register,
// or two SSE registers on a baseline build).
//
// Blocks of a reduced spatial level (high-frequency omission) store b on a coarser grid whose
// bilinear up-sampling defines the full-resolution texels; the bilinear interpolation of those
// at a query composes to ≤ 3 × 3 coarse texels (≤ 4 × 4 on tiny grids), whose weights are
// accumulated the same way.

#include <algorithm>
#include <cstring>

#include "btf/codecs/factor/model.h"
#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"
#include "btf/util/error.h"

namespace btf::factor {

namespace {

typedef float Lanes __attribute__((vector_size(32)));
constexpr int kLanes = 8;
// Largest component count per block the evaluator accepts (stack buffers are sized by it).
constexpr int kMaxComponents = 1024;
// Most spatial levels of a model (Model::validate allows no more).
constexpr int kMaxLevels = 16;

inline Lanes load(const float* p) {
    Lanes v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline void store(float* p, Lanes v) {
    std::memcpy(p, &v, sizeof v);
}
typedef float HalfLanes __attribute__((vector_size(16)));
// Pairwise: three dependent adds instead of seven.
inline float horizontal_sum(Lanes v) {
    HalfLanes s =
        __builtin_shufflevector(v, v, 0, 1, 2, 3) + __builtin_shufflevector(v, v, 4, 5, 6, 7);
    s += __builtin_shufflevector(s, s, 2, 3, 0, 1);
    s += __builtin_shufflevector(s, s, 1, 0, 3, 2);
    return s[0];
}

int padded(int k) {
    return (k + kLanes - 1) / kLanes * kLanes;
}

}  // namespace

struct FactorMaterial::Impl {
    struct BlockData {
        int k = 0, kp = 0;        // components, padded to a multiple of kLanes
        std::vector<float> a, b;  // rows × kp, texels × kp (padding is zero)
        std::vector<float> mean;  // rows (zeros when the model has none)
        bool has_mean = false;
        // Contributes nothing: no components and no mean (e.g. an unused spatial level).
        bool empty() const { return k == 0 && !has_mean; }
    };
    AngularInterpolator views, lights;
    std::vector<BlockData> blocks;
    std::vector<int32_t> cluster, local;  // per texel
    std::vector<int> group_of_view, slot_of_view;
    int nl = 0, channels = 0, planes = 0, groups = 0, clusters = 0, levels = 1, max_kp = 0;
    int width = 0, height = 0;
    ColourHandling colour;

    Impl(const Model& m)
        : views(m.sampling.views),
          lights(m.sampling.lights),
          nl(m.sampling.num_lights()),
          channels(m.colour.channels()),
          planes(m.colour.planes()),
          groups(static_cast<int>(m.groups.size())),
          clusters(m.clusters),
          levels(m.levels),
          width(m.width),
          height(m.height),
          colour(m.colour) {
        const int64_t texels = int64_t(m.width) * m.height;
        cluster.assign(texels, 0);
        local.resize(texels);
        const auto lists = m.cluster_texels();
        for (int c = 0; c < m.clusters; ++c)
            for (size_t i = 0; i < lists[c].size(); ++i) {
                cluster[lists[c][i]] = c;
                local[lists[c][i]] = static_cast<int32_t>(i);
            }
        group_of_view.resize(m.sampling.num_views());
        slot_of_view.resize(m.sampling.num_views());
        for (int g = 0; g < groups; ++g)
            for (size_t s = 0; s < m.groups[g].size(); ++s) {
                group_of_view[m.groups[g][s]] = g;
                slot_of_view[m.groups[g][s]] = static_cast<int>(s);
            }
        // The blocks of all angular levels of a (plane, group, cluster, level) become one: their
        // a columns up-sampled to every (view, light) pair, side by side.
        const int angular = m.angular_count();
        blocks.resize(m.blocks.size() / size_t(angular));
        std::vector<AngularResampler> resamplers;
        for (const AngularLevel& level : m.angular_levels)
            resamplers.emplace_back(m.sampling, level, channels);
        for (size_t i = 0; i < blocks.size(); ++i) {
            BlockData& d = blocks[i];
            const Block& first = m.blocks[i * angular];
            for (int j = 0; j < angular; ++j) d.k += m.blocks[i * angular + j].components();
            if (d.k > kMaxComponents)
                fail("factor model: block {} has {} components (at most {})", i * angular, d.k,
                     kMaxComponents);
            d.kp = padded(d.k);
            max_kp = std::max(max_kp, d.kp);
            const int64_t rows = m.rows(first.group);
            d.a.assign(rows * d.kp, 0.0f);
            d.b.assign(first.b.rows() * d.kp, 0.0f);
            for (int j = 0, k0 = 0; j < angular; ++j) {
                const Block& src = m.blocks[i * angular + j];
                if (src.components() == 0) continue;
                const Matrix a =
                    j == 0 ? src.a
                           : resamplers[size_t(j - 1)].upsample(src.a.cast<double>()).cast<float>();
                for (int64_t r = 0; r < rows; ++r)
                    for (int k = 0; k < src.components(); ++k) d.a[r * d.kp + k0 + k] = a(r, k);
                for (int64_t r = 0; r < src.b.rows(); ++r)
                    for (int k = 0; k < src.components(); ++k) d.b[r * d.kp + k0 + k] = src.b(r, k);
                k0 += src.components();
            }
            d.mean = first.mean.empty() ? std::vector<float>(size_t(rows), 0.0f) : first.mean;
            d.has_mean = !first.mean.empty();
        }
    }

    int block_index(int plane, int group, int c, int level = 0) const {
        return ((plane * groups + group) * clusters + c) * levels + level;
    }

    // Angular accumulation of one block: acc[ch·kp + k] = Σ w_v w_l a(row(v, l, ch), k) over
    // the views of `group`, and mean[ch] likewise. acc must hold channels × kp floats.
    void angular(const BlockData& d, int group, const AngularWeights& vw, const AngularWeights& lw,
                 float* acc, float* mean) const {
        // Gather the ≤ 9 (view, light) rows first, then sum them per vector: the accumulator
        // stays in a register instead of going through memory once per pair.
        const float* rows[9];
        Lanes weights[9];
        int n = 0;
        for (int ch = 0; ch < channels; ++ch) mean[ch] = 0;
        for (int v = 0; v < vw.count; ++v) {
            if (vw.weight[v] == 0 || group_of_view[vw.index[v]] != group) continue;
            const int64_t slot = slot_of_view[vw.index[v]];
            for (int l = 0; l < lw.count; ++l) {
                const float w = vw.weight[v] * lw.weight[l];
                if (w == 0) continue;
                const int64_t row = (slot * nl + lw.index[l]) * channels;
                rows[n] = d.a.data() + row * d.kp;
                weights[n++] = Lanes{} + w;
                for (int ch = 0; ch < channels; ++ch) mean[ch] += w * d.mean[row + ch];
            }
        }
        const int width = channels * d.kp;  // one (view, light) pair's rows are contiguous
        for (int i = 0; i < width; i += kLanes) {
            Lanes sum{};
            for (int k = 0; k < n; ++k) sum += weights[k] * load(rows[k] + i);
            store(acc + i, sum);
        }
    }

    // Views' groups in first-seen order (≤ 3).
    static int distinct_groups(const Impl& self, const AngularWeights& vw, int* out) {
        if (self.groups == 1) {
            out[0] = 0;
            return 1;
        }
        int n = 0;
        for (int v = 0; v < vw.count; ++v) {
            if (vw.weight[v] == 0) continue;
            const int g = self.group_of_view[vw.index[v]];
            if (std::find(out, out + n, g) == out + n) out[n++] = g;
        }
        return n;
    }

    // Texels (rows of b) and weights of a query; 4 at level 0, ≤ 16 coarse ones at other levels.
    struct Texels {
        int64_t texel[16];
        float weight[16];
        int count = 4;
        int clusters[4];
        int num_clusters = 0;
    };

    // Coarse texels along one axis of n full texels at `level` that the bilinear interpolation at
    // coordinate c reads through the up-sampling, with their weights (duplicates merged).
    struct AxisTaps {
        int index[4];
        float weight[4];
        int count = 0;
        void add(int i, float w) {
            for (int k = 0; k < count; ++k)
                if (index[k] == i) {
                    weight[k] += w;
                    return;
                }
            index[count] = i;
            weight[count++] = w;
        }
    };
    static AxisTaps axis_taps(double c, int n, int level) {
        const WrapLerp full = wrap_lerp(c, n);
        const int coarse = n >> level;
        AxisTaps taps;
        for (int k = 0; k < 2; ++k) {
            const int i = k == 0 ? full.i0 : full.i1;
            const float w = k == 0 ? 1 - full.t : full.t;
            // The coarse grid's interpolation at full texel i's centre.
            const WrapLerp up = wrap_lerp((i + 0.5) / n, coarse);
            taps.add(up.i0, w * (1 - up.t));
            taps.add(up.i1, w * up.t);
        }
        return taps;
    }
    Texels level_texels(const Uv& uv, int level) const {
        const AxisTaps tx = axis_taps(uv.u, width, level), ty = axis_taps(uv.v, height, level);
        const int64_t row = width >> level;
        Texels t;
        t.count = 0;
        for (int j = 0; j < ty.count; ++j)
            for (int i = 0; i < tx.count; ++i) {
                t.texel[t.count] = ty.index[j] * row + tx.index[i];
                t.weight[t.count++] = ty.weight[j] * tx.weight[i];
            }
        t.clusters[0] = 0;
        t.num_clusters = 1;
        return t;
    }

    // The texels of every level of a query (t: `levels` entries).
    void all_texels(const Uv& uv, Texels* t) const {
        t[0] = texels(uv, width, height);
        for (int level = 1; level < levels; ++level) t[level] = level_texels(uv, level);
    }

    Texels texels(const Uv& uv, int width, int height) const {
        const WrapLerp lx = wrap_lerp(uv.u, width), ly = wrap_lerp(uv.v, height);
        Texels t;
        t.texel[0] = int64_t(ly.i0) * width + lx.i0;
        t.texel[1] = int64_t(ly.i0) * width + lx.i1;
        t.texel[2] = int64_t(ly.i1) * width + lx.i0;
        t.texel[3] = int64_t(ly.i1) * width + lx.i1;
        t.weight[0] = (1 - lx.t) * (1 - ly.t);
        t.weight[1] = lx.t * (1 - ly.t);
        t.weight[2] = (1 - lx.t) * ly.t;
        t.weight[3] = lx.t * ly.t;
        if (clusters == 1) {
            t.clusters[0] = 0;
            t.num_clusters = 1;
            return t;
        }
        for (int j = 0; j < 4; ++j) {
            const int c = cluster[t.texel[j]];
            if (std::find(t.clusters, t.clusters + t.num_clusters, c) ==
                t.clusters + t.num_clusters)
                t.clusters[t.num_clusters++] = c;
        }
        return t;
    }

    // Spatial accumulation and the dot products of one block; adds to planes_out.
    void spatial(const BlockData& d, int cluster_id, const Texels& t, const float* acc,
                 const float* mean, float* out) const {
        alignas(32) float b[kMaxComponents];
        float weight_sum = 0;
        for (int i = 0; i < d.kp; i += kLanes) store(b + i, Lanes{});
        const bool one_cluster = clusters == 1;
        for (int j = 0; j < t.count; ++j) {
            if (!one_cluster && cluster[t.texel[j]] != cluster_id) continue;
            weight_sum += t.weight[j];
            const int64_t texel = one_cluster ? t.texel[j] : local[t.texel[j]];
            const float* row = d.b.data() + texel * d.kp;
            const Lanes w = Lanes{} + t.weight[j];
            for (int i = 0; i < d.kp; i += kLanes) store(b + i, load(b + i) + w * load(row + i));
        }
        for (int ch = 0; ch < channels; ++ch) {
            Lanes sum{};
            const float* a = acc + ch * d.kp;
            for (int i = 0; i < d.kp; i += kLanes) sum += load(a + i) * load(b + i);
            out[ch] += horizontal_sum(sum) + weight_sum * mean[ch];
        }
    }

    // The common case of one view group, one texel cluster and one level (fmf): one block per
    // plane, so the spatial accumulation is shared by all channels of a plane and needs no
    // cluster checks.
    bool single_block() const { return groups == 1 && clusters == 1 && levels == 1; }

    // Value of one query given the blocks' angular accumulations (acc: stride floats per plane,
    // mean: 3 per plane).
    Rgb single_block_value(const Uv& uv, int width, int height, const float* acc, int stride,
                           const float* mean) const {
        const WrapLerp lx = wrap_lerp(uv.u, width), ly = wrap_lerp(uv.v, height);
        const int64_t r0 = int64_t(ly.i0) * width, r1 = int64_t(ly.i1) * width;
        const int64_t t00 = r0 + lx.i0, t10 = r0 + lx.i1, t01 = r1 + lx.i0, t11 = r1 + lx.i1;
        const Lanes w00 = Lanes{} + (1 - lx.t) * (1 - ly.t), w10 = Lanes{} + lx.t * (1 - ly.t);
        const Lanes w01 = Lanes{} + (1 - lx.t) * ly.t, w11 = Lanes{} + lx.t * ly.t;
        const Lanes w[4] = {w00, w10, w01, w11};
        const int64_t t[4] = {t00, t10, t01, t11};
        float out[3] = {0, 0, 0};
        for (int p = 0; p < planes; ++p) {
            if (channels == 3)
                plane_dot<3>(blocks[p], t, w, acc + p * stride, mean + 3 * p, out + p);
            else
                plane_dot<1>(blocks[p], t, w, acc + p * stride, mean + 3 * p, out + p);
        }
        return finish(out);
    }

    // Σ_ch: out[ch] = acc[ch] · (Σ_j w_j b(t_j)) + mean[ch]; CH is a constant so that the sums
    // stay in registers.
    template <int CH>
    static void plane_dot(const BlockData& d, const int64_t* t, const Lanes* w, const float* a,
                          const float* mean, float* out) {
        const float* b0 = d.b.data() + t[0] * d.kp;
        const float* b1 = d.b.data() + t[1] * d.kp;
        const float* b2 = d.b.data() + t[2] * d.kp;
        const float* b3 = d.b.data() + t[3] * d.kp;
        Lanes sum[CH] = {};
        for (int i = 0; i < d.kp; i += kLanes) {
            const Lanes b = w[0] * load(b0 + i) + w[1] * load(b1 + i) + w[2] * load(b2 + i) +
                            w[3] * load(b3 + i);
            for (int ch = 0; ch < CH; ++ch) sum[ch] += load(a + ch * d.kp + i) * b;
        }
        for (int ch = 0; ch < CH; ++ch) out[ch] = horizontal_sum(sum[ch]) + mean[ch];
    }

    Rgb finish(const float* planes_out) const {
        return colour.inverse({planes_out[0], planes_out[1], planes_out[2]});
    }
    Rgb finish(const Rgb& planes_out) const { return colour.inverse(planes_out); }

    // The general path (several groups, clusters or levels), kept out of line so that the
    // single-block path of eval() and eval_batch() compiles as compactly as without it.
    // acc: channels × max_kp floats, mean: 3.
    __attribute__((noinline)) Rgb general_value(const Uv& uv, const AngularWeights& vw,
                                                const AngularWeights& lw, float* acc,
                                                float* mean) const {
        Texels t[kMaxLevels];
        all_texels(uv, t);
        int group_list[3];
        const int num_groups = distinct_groups(*this, vw, group_list);
        float out[3] = {0, 0, 0};
        for (int p = 0; p < planes; ++p)
            for (int gi = 0; gi < num_groups; ++gi)
                for (int level = 0; level < levels; ++level)
                    for (int ci = 0; ci < t[level].num_clusters; ++ci) {
                        const BlockData& d =
                            blocks[block_index(p, group_list[gi], t[level].clusters[ci], level)];
                        if (d.empty()) continue;
                        angular(d, group_list[gi], vw, lw, acc, mean);
                        spatial(d, t[level].clusters[ci], t[level], acc, mean, out + p);
                    }
        return finish(out);
    }

    // The same with the angular accumulations cached per block (eval_batch): block i's are at
    // cache + i · stride and cache_mean + 3 i, valid when stamp[i] == current.
    __attribute__((noinline)) Rgb general_batch_value(const Uv& uv, const AngularWeights& vw,
                                                      const AngularWeights& lw, float* cache,
                                                      float* cache_mean, uint32_t* stamp,
                                                      uint32_t current, int stride) const {
        Texels t[kMaxLevels];
        all_texels(uv, t);
        int group_list[3];
        const int num_groups = distinct_groups(*this, vw, group_list);
        float value[3] = {0, 0, 0};
        for (int p = 0; p < planes; ++p)
            for (int gi = 0; gi < num_groups; ++gi)
                for (int level = 0; level < levels; ++level)
                    for (int ci = 0; ci < t[level].num_clusters; ++ci) {
                        const int bi = block_index(p, group_list[gi], t[level].clusters[ci], level);
                        if (blocks[bi].empty()) continue;
                        float* acc = cache + int64_t(bi) * stride;
                        float* mean = cache_mean + int64_t(bi) * 3;
                        if (stamp[bi] != current) {
                            angular(blocks[bi], group_list[gi], vw, lw, acc, mean);
                            stamp[bi] = current;
                        }
                        spatial(blocks[bi], t[level].clusters[ci], t[level], acc, mean, value + p);
                    }
        return finish(value);
    }

    // Plane values of one sample (scalar, in component order).
    Rgb sample_planes(int64_t texel, int view, int light) const {
        float out[3] = {0, 0, 0};
        const int g = group_of_view[view];
        const int64_t slot = slot_of_view[view];
        float upsampled[kMaxComponents];
        for (int p = 0; p < planes; ++p)
            for (int level = 0; level < levels; ++level) {
                const BlockData& d = blocks[block_index(p, g, cluster[texel], level)];
                const float* b = nullptr;
                if (level == 0) {
                    b = d.b.data() + int64_t(local[texel]) * d.kp;
                } else {
                    // The up-sampled texel: bilinear over the coarse grid at its centre.
                    const int x = static_cast<int>(texel % width);
                    const int y = static_cast<int>(texel / width);
                    const int cw = width >> level, coarse_height = height >> level;
                    const WrapLerp ux = wrap_lerp((x + 0.5) / width, cw);
                    const WrapLerp uy = wrap_lerp((y + 0.5) / height, coarse_height);
                    const int64_t rows[4] = {
                        int64_t(uy.i0) * cw + ux.i0, int64_t(uy.i0) * cw + ux.i1,
                        int64_t(uy.i1) * cw + ux.i0, int64_t(uy.i1) * cw + ux.i1};
                    const float w[4] = {(1 - ux.t) * (1 - uy.t), ux.t * (1 - uy.t),
                                        (1 - ux.t) * uy.t, ux.t * uy.t};
                    std::fill(upsampled, upsampled + d.k, 0.0f);
                    for (int j = 0; j < 4; ++j)
                        for (int k = 0; k < d.k; ++k)
                            upsampled[k] += w[j] * d.b[rows[j] * d.kp + k];
                    b = upsampled;
                }
                for (int ch = 0; ch < channels; ++ch) {
                    const int64_t row = (slot * nl + light) * channels + ch;
                    const float* a = d.a.data() + row * d.kp;
                    float s = d.mean[row];
                    for (int k = 0; k < d.k; ++k) s += a[k] * b[k];
                    out[p + ch] += s;
                }
            }
        return {out[0], out[1], out[2]};
    }
};

FactorMaterial::FactorMaterial(Model model) : m_model(std::move(model)) {
    m_model.validate("factor model");
    m_impl = std::make_unique<Impl>(m_model);
}

FactorMaterial::~FactorMaterial() = default;

int FactorMaterial::total_components() const {
    int total = 0;
    for (const Block& b : m_model.blocks) total += b.components();
    return total;
}

Rgb FactorMaterial::eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    const Impl& m = *m_impl;
    const AngularWeights vw = m.views.weights(wo), lw = m.lights.weights(wi);
    alignas(32) float acc[3 * kMaxComponents];
    float mean[9];
    if (m.single_block()) {
        const int stride = m.channels * m.max_kp;
        for (int p = 0; p < m.planes; ++p)
            m.angular(m.blocks[p], 0, vw, lw, acc + p * stride, mean + 3 * p);
        return m.single_block_value(uv, m_model.width, m_model.height, acc, stride, mean);
    }
    return m.general_value(uv, vw, lw, acc, mean);
}

void FactorMaterial::eval_batch(std::span<const Query> queries, std::span<Rgb> out) const {
    if (queries.size() != out.size())
        fail("eval_batch: {} queries but {} outputs", queries.size(), out.size());
    const Impl& m = *m_impl;
    // Angular accumulations cached per block for the current pair of directions.
    const int stride = m.channels * std::max(m.max_kp, kLanes);
    std::vector<float> cache(m.blocks.size() * stride);
    std::vector<float> cache_mean(m.blocks.size() * 3);
    std::vector<uint32_t> stamp(m.blocks.size(), 0);
    uint32_t current = 0;
    AngularWeights vw, lw;
    Vec3 last_wi{NAN, NAN, NAN}, last_wo{NAN, NAN, NAN};
    for (size_t q = 0; q < queries.size(); ++q) {
        const Query& query = queries[q];
        if (!(query.wi.x == last_wi.x && query.wi.y == last_wi.y && query.wi.z == last_wi.z &&
              query.wo.x == last_wo.x && query.wo.y == last_wo.y && query.wo.z == last_wo.z)) {
            vw = m.views.weights(query.wo);
            lw = m.lights.weights(query.wi);
            last_wi = query.wi;
            last_wo = query.wo;
            ++current;
        }
        if (m.single_block()) {
            if (stamp[0] != current) {
                for (int p = 0; p < m.planes; ++p)
                    m.angular(m.blocks[p], 0, vw, lw, cache.data() + p * stride,
                              cache_mean.data() + 3 * p);
                stamp[0] = current;
            }
            out[q] = m.single_block_value(query.uv, m_model.width, m_model.height, cache.data(),
                                          stride, cache_mean.data());
            continue;
        }
        out[q] = m.general_batch_value(query.uv, vw, lw, cache.data(), cache_mean.data(),
                                       stamp.data(), current, stride);
    }
}

Rgb FactorMaterial::eval_sample(int x, int y, int view, int light) const {
    if (x < 0 || y < 0 || x >= m_model.width || y >= m_model.height || view < 0 ||
        view >= m_model.sampling.num_views() || light < 0 || light >= m_model.sampling.num_lights())
        fail("eval_sample: ({}, {}, view {}, light {}) is outside the material", x, y, view, light);
    return m_impl->finish(m_impl->sample_planes(int64_t(y) * m_model.width + x, view, light));
}

Rgb FactorMaterial::eval_reference(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    const Impl& m = *m_impl;
    const Rgb planes =
        lookup6d(uv, m_model.width, m_model.height, m.views.weights(wo), m.lights.weights(wi),
                 [&](int x, int y, int view, int light) {
                     return m.sample_planes(int64_t(y) * m_model.width + x, view, light);
                 });
    return m.finish(planes);
}

}  // namespace btf::factor
