// SPDX-License-Identifier: MIT
// FactorMaterial: the fast evaluator of the linear factor model.
//
// A query touches ≤ 3 views × ≤ 3 lights (angular weights w_p) and 4 texels (bilinear weights
// s_t). Because the model is linear in both factors,
//     Σ_p Σ_t w_p s_t (mean(p) + a(p) · b(t)) = Σ_p w_p mean(p) + (Σ_p w_p a(p)) · (Σ_t s_t b(t))
// within one block, so a query costs 9 + 4 vector accumulations and one dot product of length K
// per block and channel instead of 36 reconstructions. Component vectors are padded to a
// multiple of 8 and processed with compiler vector extensions (8 lanes: one AVX register, or two
// SSE registers on a baseline build). In a build for the x86-64 baseline (the Debian package) the
// out-of-line kernels below and stochastic_batch() are BTF_CLONES: the loader runs their
// x86-64-v3 or v4 clone where the processor has AVX2 or AVX-512 (util/clones.h). Each kernel is
// one function for every caller, so the batches still return the single calls' values bit for
// bit.
//
// Blocks of a reduced spatial level (high-frequency omission) store b on a coarser grid whose
// bilinear up-sampling defines the full-resolution texels; the bilinear interpolation of those
// at a query composes to ≤ 3 × 3 coarse texels (≤ 4 × 4 on tiny grids), whose weights are
// accumulated the same way.
//
// Rows in memory. A block keeps its a rows ((view, light) pairs × channels, the channels of one
// pair contiguous) and its b rows (one per texel) padded and aligned to 64-byte cache lines, in
// IEEE half floats when every factor value is one (an f16 package's factors, a UBO2014 file's
// half floats: the values the file holds, so nothing is rounded again) and in float32 otherwise.
// Loads convert 8 halves at once (F16C vcvtph2ps; exact). At K = 32 a texel's b row is then one
// line and a pair's rgb rows three, instead of two and six: a random query misses half as many
// lines, and fmf's a factor (81 × 81 pairs, 1.2 MiB in halves) nearly fits a 1 MiB L2.
//
// A single-block model (fmf, UBO2014) interleaves its planes: a texel's b rows of all planes,
// and a (view, light) pair's a rows of all planes and channels, are each one contiguous run.
//
// Random queries wait on memory and on long chains of dependent operations. A single
// eval_sample() or stochastic query reads one b run and one a run (2 to 6 lines, most of them
// misses at 256² texels), a deterministic one 9 pairs' a runs and 4 texels' b runs. The batch
// calls therefore run in stages: one looks up a later query's angular weights (and draws its
// selection) and prefetches its rows, another evaluates the query whose rows were prefetched a
// few queries earlier, so that the misses and the lookups of consecutive queries overlap instead
// of following one another (measured gains below, at kAheadDeterministic).

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <span>
#include <type_traits>

#include "btf/codecs/factor/model.h"
#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"
#include "btf/core/pick_lanes.h"
#include "btf/util/clones.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/huge_pages.h"

#if defined(__F16C__) || BTF_HAS_CLONES
#include <immintrin.h>
#endif

namespace btf::factor {

namespace {

typedef float Lanes __attribute__((vector_size(32)));
constexpr int kLanes = 8;
// Largest component count per block the evaluator accepts (stack buffers are sized by it).
constexpr int kMaxComponents = 1024;
// Most spatial levels of a model (Model::validate allows no more).
constexpr int kMaxLevels = 16;
constexpr uintptr_t kCacheLine = 64;
// Queries between prefetching a query's rows and evaluating it. Prefetching gains 1.25-1.5× on
// deterministic and 1.2-1.4× on stochastic random queries (fmf C = 32 and UBO2014 K = 32 at 256²,
// measured); any distance from 1 to 4 deterministic queries (~31 lines each) and from 4 to 32
// stochastic ones (4 to 6 lines) measured the same within 3%.
constexpr size_t kAheadDeterministic = 4;
constexpr size_t kAheadStochastic = 12;
// Ring of pending queries (a power of two above both distances).
constexpr size_t kRing = 64;

inline Lanes load(const float* p) {
    Lanes v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
#if defined(__F16C__) || BTF_HAS_CLONES
// Eight IEEE half floats as floats with F16C (exact). In a build with clones (BTF_CLONES), for the
// clones that have F16C: compiled for it by attribute, inlined into them (GCC 12 converts a vector
// of _Float16 one half at a time).
#if defined(__F16C__)
#define BTF_F16C
#else
#define BTF_F16C __attribute__((target("avx,f16c")))
#endif
BTF_F16C inline Lanes load_f16c(const uint16_t* p) {
    const __m256 v = _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
    Lanes r;
    std::memcpy(&r, &v, sizeof r);
    return r;
}
#undef BTF_F16C
#endif
// Eight IEEE half floats as floats (exact).
inline Lanes load(const uint16_t* p) {
#if defined(__F16C__)
    return load_f16c(p);
#else
#if BTF_HAS_CLONES
    // In a clone for x86-64-v3 or v4 (both have F16C) the test is always true, and load_f16c()
    // is inlined; the default clone takes the loop.
    if (__builtin_cpu_supports("x86-64-v3")) return load_f16c(p);
#endif
    Lanes r;
    for (int i = 0; i < kLanes; ++i) r[i] = from_half(p[i]);
    return r;
#endif
}
inline void store(float* p, Lanes v) {
    std::memcpy(p, &v, sizeof v);
}
// One value of a row, for the scalar reference.
inline float row_value(const float* p, int64_t i) {
    return p[i];
}
inline float row_value(const uint16_t* p, int64_t i) {
    return from_half(p[i]);
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

// Asks for the cache line of p ahead of its use. Not __builtin_prefetch: GCC counts it as free of
// side effects, so a function that only prefetches is deduced pure and its calls are deleted as
// dead code (GCC 12 at -O2 removed every prefetch of this file that way); a volatile asm stays.
inline void prefetch_line(const void* p) {
#if defined(__x86_64__) || defined(__i386__)
    asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#else
    __builtin_prefetch(p);
#endif
}

// Asks for every cache line of [p, p + bytes).
inline void prefetch_span(const void* p, size_t bytes) {
    const uintptr_t begin = reinterpret_cast<uintptr_t>(p);
    for (uintptr_t line = begin & ~(kCacheLine - 1); line < begin + bytes; line += kCacheLine)
        prefetch_line(reinterpret_cast<const void*>(line));
}

// True when two sets hold the same directions in the same order.
bool same_directions(const DirectionSet& a, const DirectionSet& b) {
    if (a.size() != b.size()) return false;
    for (int i = 0; i < a.size(); ++i)
        if (a.directions()[size_t(i)].theta != b.directions()[size_t(i)].theta ||
            a.directions()[size_t(i)].phi != b.directions()[size_t(i)].phi)
            return false;
    return true;
}

// The filter number as ShadingPoint clamps it before Material::select().
inline double clamp_filter_number(double u) {
    if (!(u >= 0)) u = 0;  // NaN too
    return std::min(u, 0x1.fffffffffffffp-1);
}

// A zero-initialized array of float or half rows that starts on a cache line, so that rows whose
// size is a multiple of 64 bytes (K = 32 in halves, K = 16 in floats) lie in whole lines; on huge
// pages where large (huge_pages.h).
class LineAlignedRows {
  public:
    template <typename T>
    void assign(size_t count) {
        const size_t bytes = (count * sizeof(T) + kCacheLine - 1) / kCacheLine * kCacheLine;
        m_data.reset();
        if (bytes == 0) return;
        m_data.reset(static_cast<std::byte*>(allocate_table(bytes, kCacheLine)));
        std::memset(m_data.get(), 0, bytes);
    }
    template <typename T>
    T* data() {
        return reinterpret_cast<T*>(m_data.get());
    }
    template <typename T>
    const T* data() const {
        return reinterpret_cast<const T*>(m_data.get());
    }

  private:
    struct Free {
        void operator()(std::byte* p) const { free_table(p); }
    };
    std::unique_ptr<std::byte, Free> m_data;
};

// True when every value converts to an IEEE half float and back unchanged.
bool all_halves(const float* v, size_t n) {
    for (size_t i = 0; i < n; ++i)
        if (!(from_half(to_half(v[i])) == v[i])) return false;
    return true;
}

// One value as a row of T stores it.
inline void put_value(float* out, float v) {
    *out = v;
}
inline void put_value(uint16_t* out, float v) {
    *out = to_half(v);
}

// Queries drawn at once by eval_stochastic_batch(): one per lane of pick_lanes().
constexpr size_t kGroup = kPickLanes;
typedef PickLanes Group;
typedef PickMask GroupMask;
typedef PickMask GroupIndex;

}  // namespace

struct FactorMaterial::Impl {
    // One block's rows in Impl::storage: the rows of (view, light) pair p (its channels' rows of
    // kp values each, contiguous) at p · a_stride, the row of texel t at t · b_stride, in floats
    // or in IEEE half bits when Impl::half (padding is zero).
    struct BlockData {
        int k = 0, kp = 0;  // components, padded to a multiple of kLanes
        int64_t a_stride = 0, b_stride = 0;
        const std::byte* a_base = nullptr;
        const std::byte* b_base = nullptr;
        std::vector<float> mean;  // pairs × channels (zeros when the model has none)
        bool has_mean = false;
        // Contributes nothing: no components and no mean (e.g. an unused spatial level).
        bool empty() const { return k == 0 && !has_mean; }
        template <typename T>
        const T* a_pair(int64_t pair) const {
            return reinterpret_cast<const T*>(a_base) + pair * a_stride;
        }
        template <typename T>
        const T* b_texel(int64_t texel) const {
            return reinterpret_cast<const T*>(b_base) + texel * b_stride;
        }
    };
    // A single-block model (one view group, one cluster, one level: fmf, UBO2014) keeps the rows
    // of its planes interleaved: a pair's a rows of every plane and channel side by side, and a
    // texel's b rows of every plane side by side. A query then reads one run of lines per factor
    // instead of one per plane (UBO2014's 3 per-channel planes: 3 lines in one page, not in
    // three), and the 3 output values k (channels or planes) are dot products of segments:
    //     value_k = a(pair)[a_offset_k, + kp_k) · b(texel)[b_offset_k, + kp_k) + mean(pair, k).
    struct Fused {
        int a_width = 0, b_width = 0;  // values per pair, per texel
        int kp[3] = {0, 0, 0}, a_offset[3] = {0, 0, 0}, b_offset[3] = {0, 0, 0};
        bool shared_b = false;  // one plane: its 3 channels read the same b row
        // 3 planes of as many components each (UBO2014 DFMF): segment k at k · kp[0] in both.
        bool equal_planes = false;
        bool has_mean = false;
        std::vector<float> mean;  // pairs × 3
        const std::byte* a = nullptr;
        const std::byte* b = nullptr;
    };
    AngularInterpolator views, lights;
    // `lights`, or `views` when both are built from the same directions (the UBO 81 × 81 of fmf
    // and UBO2014 files): the same weights, and one lookup grid in the caches instead of two.
    const AngularInterpolator* light_lookup = nullptr;
    std::vector<BlockData> blocks;
    Fused fused;
    std::vector<LineAlignedRows> storage;  // the arrays the blocks' rows lie in
    std::vector<int32_t> cluster, local;   // per texel
    std::vector<int> group_of_view, slot_of_view;
    int nl = 0, channels = 0, planes = 0, groups = 0, clusters = 0, levels = 1, max_kp = 0;
    int width = 0, height = 0;
    ColourHandling colour;
    bool half = false;  // rows in IEEE half floats
    // colour.inverse() returns its argument (rgb or per-channel planes without log).
    bool identity_colour = false;

    Impl(const Model& m, RowStorage storage_choice)
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
        light_lookup = same_directions(m.sampling.views, m.sampling.lights) ? &views : &lights;
        identity_colour = !colour.log && (colour.basis == ColourBasis::kRgb ||
                                          colour.basis == ColourBasis::kPerChannel);
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
        // Float rows per block first. The blocks of all angular levels of a (plane, group,
        // cluster, level) become one: their a columns up-sampled to every (view, light) pair,
        // side by side.
        const int angular = m.angular_count();
        blocks.resize(m.blocks.size() / size_t(angular));
        std::vector<LineAlignedRows> a_rows(blocks.size()), b_rows(blocks.size());
        std::vector<int64_t> a_count(blocks.size()), b_count(blocks.size());
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
            a_count[i] = rows * d.kp;
            b_count[i] = first.b.rows() * d.kp;
            a_rows[i].assign<float>(size_t(a_count[i]));
            b_rows[i].assign<float>(size_t(b_count[i]));
            float* da = a_rows[i].data<float>();
            float* db = b_rows[i].data<float>();
            for (int j = 0, k0 = 0; j < angular; ++j) {
                const Block& src = m.blocks[i * angular + j];
                if (src.components() == 0) continue;
                const Matrix a =
                    j == 0 ? src.a
                           : resamplers[size_t(j - 1)].upsample(src.a.cast<double>()).cast<float>();
                for (int64_t r = 0; r < rows; ++r)
                    for (int k = 0; k < src.components(); ++k) da[r * d.kp + k0 + k] = a(r, k);
                for (int64_t r = 0; r < src.b.rows(); ++r)
                    for (int k = 0; k < src.components(); ++k) db[r * d.kp + k0 + k] = src.b(r, k);
                k0 += src.components();
            }
            d.mean = first.mean.empty() ? std::vector<float>(size_t(rows), 0.0f) : first.mean;
            d.has_mean = !first.mean.empty();
        }
        // Half rows only when no value changes: then every evaluation gives what float rows give,
        // bit for bit (the conversion is exact and the arithmetic the same). Up-sampled angular
        // levels and u8 or f32 factors are not halves in general and keep float rows.
        half = storage_choice == RowStorage::kAuto;
        for (size_t i = 0; half && i < blocks.size(); ++i)
            half = all_halves(a_rows[i].data<float>(), size_t(a_count[i])) &&
                   all_halves(b_rows[i].data<float>(), size_t(b_count[i]));
        if (half)
            lay_out<uint16_t>(a_rows, b_rows, a_count, b_count);
        else
            lay_out<float>(a_rows, b_rows, a_count, b_count);
    }

    // Moves the float rows per block (stride kp; a_count, b_count values) into their final
    // layout in T: interleaved planes for a single block, else one pair of arrays per block.
    template <typename T>
    void lay_out(std::vector<LineAlignedRows>& a_rows, std::vector<LineAlignedRows>& b_rows,
                 const std::vector<int64_t>& a_count, const std::vector<int64_t>& b_count) {
        if (!single_block()) {
            for (size_t i = 0; i < blocks.size(); ++i) {
                BlockData& d = blocks[i];
                // The vector may move its elements; the arrays they own stay where they are.
                storage.push_back(convert<T>(a_rows[i], size_t(a_count[i])));
                d.a_base = reinterpret_cast<const std::byte*>(storage.back().data<T>());
                storage.push_back(convert<T>(b_rows[i], size_t(b_count[i])));
                d.b_base = reinterpret_cast<const std::byte*>(storage.back().data<T>());
                d.a_stride = int64_t(channels) * d.kp;
                d.b_stride = d.kp;
            }
            return;
        }
        const int64_t texels = int64_t(width) * height;
        Fused& f = fused;
        const int64_t pairs = int64_t(slot_of_view.size()) * nl;
        int a_offset[3], b_offset[3];
        for (int p = 0; p < planes; ++p) {
            a_offset[p] = f.a_width;
            b_offset[p] = planes == 1 ? 0 : f.b_width;
            f.a_width += channels * blocks[p].kp;
            if (planes > 1 || p == 0) f.b_width += blocks[p].kp;
        }
        LineAlignedRows a, b;
        a.assign<T>(size_t(pairs * f.a_width));
        b.assign<T>(size_t(texels * f.b_width));
        for (int p = 0; p < planes; ++p) {
            const int a_run = channels * blocks[p].kp, b_run = blocks[p].kp;
            const float* src_a = a_rows[p].data<float>();
            const float* src_b = b_rows[p].data<float>();
            for (int64_t pair = 0; pair < pairs; ++pair)
                for (int i = 0; i < a_run; ++i)
                    put_value(a.data<T>() + pair * f.a_width + a_offset[p] + i,
                              src_a[pair * a_run + i]);
            for (int64_t t = 0; t < texels; ++t)
                for (int i = 0; i < b_run; ++i)
                    put_value(b.data<T>() + t * f.b_width + b_offset[p] + i, src_b[t * b_run + i]);
            a_rows[p].assign<float>(0);
            b_rows[p].assign<float>(0);
        }
        storage.push_back(std::move(a));
        storage.push_back(std::move(b));
        f.a = reinterpret_cast<const std::byte*>(storage[0].data<T>());
        f.b = reinterpret_cast<const std::byte*>(storage[1].data<T>());
        f.shared_b = planes == 1;
        f.equal_planes =
            planes == 3 && blocks[0].kp == blocks[1].kp && blocks[1].kp == blocks[2].kp;
        f.mean.assign(size_t(pairs) * 3, 0.0f);
        for (int k = 0; k < 3; ++k) {
            const int p = planes == 1 ? 0 : k;
            const BlockData& d = blocks[p];
            f.kp[k] = d.kp;
            f.a_offset[k] = a_offset[p] + (planes == 1 ? k * d.kp : 0);
            f.b_offset[k] = b_offset[p];
            f.has_mean = f.has_mean || d.has_mean;
            for (int64_t pair = 0; pair < pairs; ++pair)
                f.mean[size_t(pair * 3 + k)] = d.mean[size_t(planes == 1 ? pair * 3 + k : pair)];
        }
        for (int p = 0; p < planes; ++p) {
            BlockData& d = blocks[p];
            d.a_base = f.a + sizeof(T) * size_t(a_offset[p]);
            d.b_base = f.b + sizeof(T) * size_t(b_offset[p]);
            d.a_stride = f.a_width;
            d.b_stride = f.b_width;
        }
    }

    // `count` values of float rows as rows of T.
    template <typename T>
    static LineAlignedRows convert(LineAlignedRows& rows, size_t count) {
        if constexpr (std::is_same_v<T, float>) {
            return std::move(rows);
        } else {
            LineAlignedRows out;
            out.assign<T>(count);
            for (size_t i = 0; i < count; ++i) put_value(out.data<T>() + i, rows.data<float>()[i]);
            return out;
        }
    }

    int block_index(int plane, int group, int c, int level = 0) const {
        return ((plane * groups + group) * clusters + c) * levels + level;
    }

    // The common case of one view group, one texel cluster and one level (fmf, UBO2014): one
    // block per plane, laid out as Fused.
    bool single_block() const { return groups == 1 && clusters == 1 && levels == 1; }

    template <typename T>
    const T* fused_a(int64_t pair) const {
        return reinterpret_cast<const T*>(fused.a) + pair * fused.a_width;
    }
    template <typename T>
    const T* fused_b(int64_t texel) const {
        return reinterpret_cast<const T*>(fused.b) + texel * fused.b_width;
    }

    Rgb finish(const float* planes_out) const {
        return finish(Rgb{planes_out[0], planes_out[1], planes_out[2]});
    }
    Rgb finish(const Rgb& planes_out) const {
        return identity_colour ? planes_out : colour.inverse(planes_out);
    }

    // ---- selection (stochastic filter) --------------------------------------------------------

    // What a stochastic query draws from: its texel axes and both angular weights.
    // stochastic_batch() looks them up a group of queries ahead of the picks, which wait for them,
    // four directions at once (AngularInterpolator::weights4): a lookup by weights() takes 59 ns
    // from direction to weights, 26 ns when independent ones overlap (measured).
    struct Weighed {
        WrapLerp lx, ly;
        AngularWeights vw, lw;
    };
    // The same for kGroup queries, as weights4() writes them.
    struct WeighedGroup {
        WrapLerp lx[kGroup], ly[kGroup];
        std::array<AngularWeights, kGroup> vw, lw;
    };
    // The picks of Material::select(), statement for statement, given the query's weights (from
    // this material's interpolators: the same triangulations of the same directions as
    // Material::view_interpolator() and light_interpolator(), so the same weights), with picks
    // without branches (the same draws).
    Selection draw(const Weighed& w, double u) const {
        Selection s;
        s.u = u;
        s.view = w.vw.index[size_t(pick<3>(w.vw.weight.data(), w.vw.count, s.u))];
        const float wx[2] = {1 - w.lx.t, w.lx.t}, wy[2] = {1 - w.ly.t, w.ly.t};
        s.x = pick<2>(wx, 2, s.u) == 0 ? w.lx.i0 : w.lx.i1;
        s.y = pick<2>(wy, 2, s.u) == 0 ? w.ly.i0 : w.ly.i1;
        return s;
    }
    // The light Material::eval_selected() draws from the weights of wi with what is left of the
    // number, u.
    static int draw_light(const AngularWeights& lw, double u) {
        return lw.index[size_t(pick<3>(lw.weight.data(), lw.count, u))];
    }
    struct Drawn {
        int64_t texel;
        int view, light;
    };
    // draw() and draw_light() for kGroup queries at once, one per lane: the same operations on
    // the same doubles, so the same draws bit for bit, with kGroup chains of picks in flight
    // instead of one. The 4 dependent picks of a query (3 divisions) take 45 ns, and one query's
    // chain hardly overlaps the next one's (fmf C = 32 stochastic batch: 116 ns per query with
    // draw() query by query, 102 ns by groups, measured).
    void draw_group(const WeighedGroup& w, const double* numbers, Drawn* out) const {
        static_assert(kGroup == 4);
        // Vectors built whole from their lanes' values: written lane by lane, they would go
        // through memory, and each vector's load would wait for its lanes' stores.
        auto lanes = [](auto value) { return Group{value(0), value(1), value(2), value(3)}; };
        auto mask_lanes = [](auto is) {
            return GroupMask{is(0) ? -1 : 0, is(1) ? -1 : 0, is(2) ? -1 : 0, is(3) ? -1 : 0};
        };
        Group u = {numbers[0], numbers[1], numbers[2], numbers[3]}, t;
        // As draw(): the weights are floats, 1 − t rounded to float first.
        const Group wx[2] = {lanes([&](int j) { return double(1 - w.lx[j].t); }),
                             lanes([&](int j) { return double(w.lx[j].t); })};
        const Group wy[2] = {lanes([&](int j) { return double(1 - w.ly[j].t); }),
                             lanes([&](int j) { return double(w.ly[j].t); })};
        Group wv[3], wl[3];
        GroupMask count_v[3], count_l[3];
        // Loops unrolled: their vectors stay in registers rather than in arrays in memory.
#pragma GCC unroll 3
        for (int i = 0; i < 3; ++i) {
            wv[i] = lanes([&](int j) { return double(w.vw[j].weight[size_t(i)]); });
            wl[i] = lanes([&](int j) { return double(w.lw[j].weight[size_t(i)]); });
            count_v[i] = mask_lanes([&](int j) { return w.vw[j].count == i + 1; });
            count_l[i] = mask_lanes([&](int j) { return w.lw[j].count == i + 1; });
            // As pick(): entries from the count on do not count.
            wv[i] = mask_lanes([&](int j) { return w.vw[j].count > i; }) ? wv[i] : Group{};
            wl[i] = mask_lanes([&](int j) { return w.lw[j].count > i; }) ? wl[i] : Group{};
        }
        const GroupMask last2[2] = {GroupMask{}, ~GroupMask{}};
        const GroupIndex v = pick_lanes<3>(wv, count_v, u);
        const GroupIndex x = pick_lanes<2>(wx, last2, u);
        const GroupIndex y = pick_lanes<2>(wy, last2, u);
        t = u;
        const GroupIndex l = pick_lanes<3>(wl, count_l, t);
#pragma GCC unroll 4
        for (size_t j = 0; j < kGroup; ++j) {
            const int sx = x[j] == 0 ? w.lx[j].i0 : w.lx[j].i1;
            const int sy = y[j] == 0 ? w.ly[j].i0 : w.ly[j].i1;
            out[j] = {int64_t(sy) * width + sx, w.vw[j].index[size_t(v[j])],
                      w.lw[j].index[size_t(l[j])]};
        }
    }

    Selection select(const Uv& uv, const Vec3& wo, double u) const {
        Weighed w;
        w.lx = wrap_lerp(uv.u, width);
        w.ly = wrap_lerp(uv.v, height);
        w.vw = views.weights(wo);
        return draw(w, u);
    }
    int pick_light(const Vec3& wi, double u) const {
        return draw_light(light_lookup->weights(wi), u);
    }

    // ---- one sample (eval_sample, the stochastic filter) ----------------------------------------

    // Plane values of one sample, vectorized over components.
    template <typename T>
    Rgb sample(int64_t texel, int view, int light) const {
        float out[3] = {0, 0, 0};
        const int64_t pair = int64_t(slot_of_view[view]) * nl + light;
        if (single_block())
            fused_sample<T>(texel, pair, out);
        else
            general_sample<T>(texel, group_of_view[view], pair, out);
        return {out[0], out[1], out[2]};
    }

    // One sample of a single block. Out of line, and the one body that eval_sample(),
    // eval_selected() and eval_stochastic_batch() call: inlined into each, GCC could contract
    // multiplies and adds into fused ones differently, and the batch would no longer return
    // exactly the shading point's values.
    template <typename T>
    __attribute__((noinline)) BTF_CLONES void fused_sample(int64_t texel, int64_t pair,
                                                           float* out) const {
        const Fused& f = fused;
        const T* a = fused_a<T>(pair);
        const T* b = fused_b<T>(texel);
        // Three named sums: GCC keeps an array of them in memory.
        Lanes s0{}, s1{}, s2{};
        if (f.shared_b) {
            const int kp = f.kp[0];
            for (int i = 0; i < kp; i += kLanes) {
                const Lanes bv = load(b + i);
                s0 += load(a + i) * bv;
                s1 += load(a + kp + i) * bv;
                s2 += load(a + 2 * kp + i) * bv;
            }
        } else if (f.equal_planes) {
            // The loop below in one: every line of both rows is asked for at once.
            const int kp = f.kp[0];
            for (int i = 0; i < kp; i += kLanes) {
                s0 += load(a + i) * load(b + i);
                s1 += load(a + kp + i) * load(b + kp + i);
                s2 += load(a + 2 * kp + i) * load(b + 2 * kp + i);
            }
        } else {
            for (int i = 0; i < f.kp[0]; i += kLanes)
                s0 += load(a + f.a_offset[0] + i) * load(b + f.b_offset[0] + i);
            for (int i = 0; i < f.kp[1]; i += kLanes)
                s1 += load(a + f.a_offset[1] + i) * load(b + f.b_offset[1] + i);
            for (int i = 0; i < f.kp[2]; i += kLanes)
                s2 += load(a + f.a_offset[2] + i) * load(b + f.b_offset[2] + i);
        }
        out[0] = horizontal_sum(s0);
        out[1] = horizontal_sum(s1);
        out[2] = horizontal_sum(s2);
        if (f.has_mean)
            for (int k = 0; k < 3; ++k) out[k] += f.mean[size_t(pair * 3 + k)];
    }

    // out[ch] += a(pair, ch) · b + mean(pair, ch) for CH channels: b is one row of kp components
    // (the block's own, TA = TB, or an up-sampled row in floats). CH is a constant so that the
    // sums stay in registers.
    template <int CH, typename TA, typename TB>
    static void sample_dot(const BlockData& d, const TB* b, int64_t pair, float* out) {
        const TA* a = d.a_pair<TA>(pair);
        Lanes sum[CH] = {};
        for (int i = 0; i < d.kp; i += kLanes) {
            const Lanes bv = load(b + i);
            for (int ch = 0; ch < CH; ++ch) sum[ch] += load(a + ch * d.kp + i) * bv;
        }
        for (int ch = 0; ch < CH; ++ch)
            out[ch] += horizontal_sum(sum[ch]) + (d.has_mean ? d.mean[pair * CH + ch] : 0.0f);
    }
    template <typename TA, typename TB>
    void sample_dot(const BlockData& d, const TB* b, int64_t pair, float* out) const {
        if (channels == 3)
            sample_dot<3, TA>(d, b, pair, out);
        else
            sample_dot<1, TA>(d, b, pair, out);
    }

    // Several groups, clusters or levels: the texel's block of each level, and at reduced levels
    // its row up-sampled from 4 coarse rows first. Out of line, so that the single-block path of
    // the batches compiles as compactly as without it.
    template <typename T>
    __attribute__((noinline)) BTF_CLONES void general_sample(int64_t texel, int group, int64_t pair,
                                                             float* out) const {
        const int c = cluster[texel];
        alignas(32) float upsampled[kMaxComponents];
        for (int p = 0; p < planes; ++p)
            for (int level = 0; level < levels; ++level) {
                const BlockData& d = blocks[block_index(p, group, c, level)];
                if (level == 0) {
                    sample_dot<T>(d, d.b_texel<T>(local[texel]), pair, out + p);
                    continue;
                }
                int64_t coarse[4];
                float w[4];
                upsampling_taps(texel, level, coarse, w);
                const T* b0 = d.b_texel<T>(coarse[0]);
                const T* b1 = d.b_texel<T>(coarse[1]);
                const T* b2 = d.b_texel<T>(coarse[2]);
                const T* b3 = d.b_texel<T>(coarse[3]);
                const Lanes w0 = Lanes{} + w[0], w1 = Lanes{} + w[1], w2 = Lanes{} + w[2],
                            w3 = Lanes{} + w[3];
                for (int i = 0; i < d.kp; i += kLanes)
                    store(upsampled + i, w0 * load(b0 + i) + w1 * load(b1 + i) + w2 * load(b2 + i) +
                                             w3 * load(b3 + i));
                sample_dot<T>(d, static_cast<const float*>(upsampled), pair, out + p);
            }
    }

    // The 4 coarse texels of `level` whose bilinear interpolation at full texel `texel`'s centre
    // is its up-sampled row, and their weights.
    void upsampling_taps(int64_t texel, int level, int64_t* coarse, float* w) const {
        const int x = static_cast<int>(texel % width);
        const int y = static_cast<int>(texel / width);
        const int cw = width >> level, coarse_height = height >> level;
        const WrapLerp ux = wrap_lerp((x + 0.5) / width, cw);
        const WrapLerp uy = wrap_lerp((y + 0.5) / height, coarse_height);
        coarse[0] = int64_t(uy.i0) * cw + ux.i0;
        coarse[1] = int64_t(uy.i0) * cw + ux.i1;
        coarse[2] = int64_t(uy.i1) * cw + ux.i0;
        coarse[3] = int64_t(uy.i1) * cw + ux.i1;
        w[0] = (1 - ux.t) * (1 - uy.t);
        w[1] = ux.t * (1 - uy.t);
        w[2] = (1 - ux.t) * uy.t;
        w[3] = ux.t * uy.t;
    }

    // Prefetches what sample() will read: the a and b rows (level 0 of a single cluster; with
    // several clusters where a row lies is itself a load away).
    template <typename T>
    void prefetch_sample(int64_t texel, int view, int light) const {
        const int64_t pair = int64_t(slot_of_view[view]) * nl + light;
        if (single_block()) {
            prefetch_span(fused_a<T>(pair), size_t(fused.a_width) * sizeof(T));
            prefetch_span(fused_b<T>(texel), size_t(fused.b_width) * sizeof(T));
            if (fused.has_mean) prefetch_line(fused.mean.data() + pair * 3);
            return;
        }
        if (clusters != 1) return;
        const int group = group_of_view[view];
        for (int p = 0; p < planes; ++p) {
            const BlockData& d = blocks[block_index(p, group, 0, 0)];
            prefetch_span(d.b_texel<T>(texel), size_t(d.kp) * sizeof(T));
            prefetch_span(d.a_pair<T>(pair), size_t(channels * d.kp) * sizeof(T));
            if (d.has_mean) prefetch_line(d.mean.data() + pair * channels);
        }
    }

    // Plane values of one sample in plain scalar code, component by component: the reference.
    template <typename T>
    Rgb sample_reference(int64_t texel, int view, int light) const {
        float out[3] = {0, 0, 0};
        const int g = group_of_view[view];
        const int64_t pair = int64_t(slot_of_view[view]) * nl + light;
        float upsampled[kMaxComponents];
        for (int p = 0; p < planes; ++p)
            for (int level = 0; level < levels; ++level) {
                const BlockData& d = blocks[block_index(p, g, cluster[texel], level)];
                if (level == 0) {
                    for (int k = 0; k < d.k; ++k)
                        upsampled[k] = row_value(d.b_texel<T>(local[texel]), k);
                } else {
                    // The up-sampled texel: bilinear over the coarse grid at its centre.
                    int64_t coarse[4];
                    float w[4];
                    upsampling_taps(texel, level, coarse, w);
                    std::fill(upsampled, upsampled + d.k, 0.0f);
                    for (int j = 0; j < 4; ++j)
                        for (int k = 0; k < d.k; ++k)
                            upsampled[k] += w[j] * row_value(d.b_texel<T>(coarse[j]), k);
                }
                for (int ch = 0; ch < channels; ++ch) {
                    float s = d.mean[size_t(pair * channels + ch)];
                    for (int k = 0; k < d.k; ++k)
                        s += row_value(d.a_pair<T>(pair), ch * d.kp + k) * upsampled[k];
                    out[p + ch] += s;
                }
            }
        return {out[0], out[1], out[2]};
    }

    // ---- interpolated evaluation: one block ----------------------------------------------------

    // The 4 texels and bilinear weights of a query at full resolution.
    struct Bilinear {
        int64_t t[4];
        Lanes w[4];
    };
    Bilinear bilinear(const Uv& uv) const {
        const WrapLerp lx = wrap_lerp(uv.u, width), ly = wrap_lerp(uv.v, height);
        const int64_t r0 = int64_t(ly.i0) * width, r1 = int64_t(ly.i1) * width;
        return {{r0 + lx.i0, r0 + lx.i1, r1 + lx.i0, r1 + lx.i1},
                {Lanes{} + (1 - lx.t) * (1 - ly.t), Lanes{} + lx.t * (1 - ly.t),
                 Lanes{} + (1 - lx.t) * ly.t, Lanes{} + lx.t * ly.t}};
    }

    // Angular accumulation of a single block: acc[i] = Σ w_v w_l a(pair(v, l))[i] over the
    // fused width, and mean[k] likewise. acc must hold fused.a_width floats. Out of line like
    // fused_value(), so that eval() and eval_batch() share one body and agree bit for bit.
    template <typename T>
    __attribute__((noinline)) BTF_CLONES void fused_angular(const AngularWeights& vw,
                                                            const AngularWeights& lw, float* acc,
                                                            float* mean) const {
        // Gather the ≤ 9 pairs' rows first, then sum them per vector: the accumulator stays in
        // a register instead of going through memory once per pair.
        const T* rows[9];
        Lanes weights[9];
        int n = 0;
        mean[0] = mean[1] = mean[2] = 0;
        for (int v = 0; v < vw.count; ++v) {
            if (vw.weight[v] == 0) continue;
            const int64_t slot = slot_of_view[vw.index[v]];
            for (int l = 0; l < lw.count; ++l) {
                const float w = vw.weight[v] * lw.weight[l];
                if (w == 0) continue;
                const int64_t pair = slot * nl + lw.index[l];
                rows[n] = fused_a<T>(pair);
                weights[n++] = Lanes{} + w;
                // Without row means the sum stays 0, as it would summing the zeros.
                if (fused.has_mean)
                    for (int k = 0; k < 3; ++k) mean[k] += w * fused.mean[size_t(pair * 3 + k)];
            }
        }
        for (int i = 0; i < fused.a_width; i += kLanes) {
            Lanes sum{};
            for (int k = 0; k < n; ++k) sum += weights[k] * load(rows[k] + i);
            store(acc + i, sum);
        }
    }

    // Value of one query given the angular accumulation: Σ_t s_t b(t) per segment, dotted with
    // acc's segment.
    template <typename T>
    __attribute__((noinline)) BTF_CLONES Rgb fused_value(const Uv& uv, const float* acc,
                                                         const float* mean) const {
        const Fused& f = fused;
        const Bilinear q = bilinear(uv);
        const T* b0 = fused_b<T>(q.t[0]);
        const T* b1 = fused_b<T>(q.t[1]);
        const T* b2 = fused_b<T>(q.t[2]);
        const T* b3 = fused_b<T>(q.t[3]);
        Lanes sum[3] = {};
        if (f.shared_b) {
            const int kp = f.kp[0];
            for (int i = 0; i < kp; i += kLanes) {
                const Lanes b = q.w[0] * load(b0 + i) + q.w[1] * load(b1 + i) +
                                q.w[2] * load(b2 + i) + q.w[3] * load(b3 + i);
                for (int k = 0; k < 3; ++k) sum[k] += load(acc + k * kp + i) * b;
            }
        } else {
            for (int k = 0; k < 3; ++k)
                for (int i = f.b_offset[k]; i < f.b_offset[k] + f.kp[k]; i += kLanes) {
                    const Lanes b = q.w[0] * load(b0 + i) + q.w[1] * load(b1 + i) +
                                    q.w[2] * load(b2 + i) + q.w[3] * load(b3 + i);
                    sum[k] += load(acc + f.a_offset[k] - f.b_offset[k] + i) * b;
                }
        }
        const float out[3] = {horizontal_sum(sum[0]) + mean[0], horizontal_sum(sum[1]) + mean[1],
                              horizontal_sum(sum[2]) + mean[2]};
        return finish(out);
    }

    // Prefetches the a rows (and row means) fused_angular() will read for these weights.
    template <typename T>
    void prefetch_angular(const AngularWeights& vw, const AngularWeights& lw) const {
        for (int v = 0; v < vw.count; ++v) {
            if (vw.weight[v] == 0) continue;
            const int64_t slot = slot_of_view[vw.index[v]];
            for (int l = 0; l < lw.count; ++l) {
                if (lw.weight[l] == 0) continue;
                const int64_t pair = slot * nl + lw.index[l];
                prefetch_span(fused_a<T>(pair), size_t(fused.a_width) * sizeof(T));
                if (fused.has_mean) prefetch_line(fused.mean.data() + pair * 3);
            }
        }
    }

    // Prefetches the b rows fused_value() will read at uv.
    template <typename T>
    void prefetch_bilinear(const Uv& uv) const {
        const Bilinear q = bilinear(uv);
        for (int j = 0; j < 4; ++j)
            prefetch_span(fused_b<T>(q.t[j]), size_t(fused.b_width) * sizeof(T));
    }

    // ---- interpolated evaluation: several blocks -----------------------------------------------

    // Angular accumulation of one block: acc[ch·kp + k] = Σ w_v w_l a(pair(v, l), ch, k) over
    // the views of `group`, and mean[ch] likewise. acc must hold channels × kp floats.
    template <typename T>
    void angular(const BlockData& d, int group, const AngularWeights& vw, const AngularWeights& lw,
                 float* acc, float* mean) const {
        const T* rows[9];
        Lanes weights[9];
        int n = 0;
        for (int ch = 0; ch < channels; ++ch) mean[ch] = 0;
        for (int v = 0; v < vw.count; ++v) {
            if (vw.weight[v] == 0 || group_of_view[vw.index[v]] != group) continue;
            const int64_t slot = slot_of_view[vw.index[v]];
            for (int l = 0; l < lw.count; ++l) {
                const float w = vw.weight[v] * lw.weight[l];
                if (w == 0) continue;
                const int64_t pair = slot * nl + lw.index[l];
                rows[n] = d.a_pair<T>(pair);
                weights[n++] = Lanes{} + w;
                if (d.has_mean)
                    for (int ch = 0; ch < channels; ++ch)
                        mean[ch] += w * d.mean[size_t(pair * channels + ch)];
            }
        }
        const int width = channels * d.kp;  // one pair's rows are contiguous
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
        t[0] = texels(uv);
        for (int level = 1; level < levels; ++level) t[level] = level_texels(uv, level);
    }

    Texels texels(const Uv& uv) const {
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
    template <typename T>
    void spatial(const BlockData& d, int cluster_id, const Texels& t, const float* acc,
                 const float* mean, float* out) const {
        alignas(32) float b[kMaxComponents];
        float weight_sum = 0;
        for (int i = 0; i < d.kp; i += kLanes) store(b + i, Lanes{});
        const bool one_cluster = clusters == 1;
        for (int j = 0; j < t.count; ++j) {
            if (!one_cluster && cluster[t.texel[j]] != cluster_id) continue;
            weight_sum += t.weight[j];
            const T* row = d.b_texel<T>(one_cluster ? t.texel[j] : local[t.texel[j]]);
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

    // The general path (several groups, clusters or levels), kept out of line so that the
    // single-block path of eval() and eval_batch() compiles as compactly as without it.
    // acc: channels × max_kp floats, mean: 3.
    template <typename T>
    __attribute__((noinline)) BTF_CLONES Rgb general_value(const Uv& uv, const AngularWeights& vw,
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
                        angular<T>(d, group_list[gi], vw, lw, acc, mean);
                        spatial<T>(d, t[level].clusters[ci], t[level], acc, mean, out + p);
                    }
        return finish(out);
    }

    // The same with the angular accumulations cached per block (eval_batch): block i's are at
    // cache + i · stride and cache_mean + 3 i, valid when stamp[i] == current.
    template <typename T>
    __attribute__((noinline)) BTF_CLONES Rgb general_batch_value(
        const Uv& uv, const AngularWeights& vw, const AngularWeights& lw, float* cache,
        float* cache_mean, uint32_t* stamp, uint32_t current, int stride) const {
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
                            angular<T>(blocks[bi], group_list[gi], vw, lw, acc, mean);
                            stamp[bi] = current;
                        }
                        spatial<T>(blocks[bi], t[level].clusters[ci], t[level], acc, mean,
                                   value + p);
                    }
        return finish(value);
    }

    // ---- the calls ------------------------------------------------------------------------------

    template <typename T>
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
        const AngularWeights vw = views.weights(wo), lw = light_lookup->weights(wi);
        alignas(32) float acc[3 * kMaxComponents];
        float mean[3];
        if (single_block()) {
            fused_angular<T>(vw, lw, acc, mean);
            return fused_value<T>(uv, acc, mean);
        }
        return general_value<T>(uv, vw, lw, acc, mean);
    }

    // eval_batch() of a single block in two stages: the weights of query i + kAhead are computed
    // and its rows prefetched while query i is evaluated. Consecutive queries with the same
    // directions share one angular accumulation (a coherent batch computes it once).
    template <typename T>
    void single_block_batch(std::span<const Query> queries, std::span<Rgb> out) const {
        constexpr size_t kAhead = kAheadDeterministic;
        struct Pending {
            AngularWeights vw, lw;
            uint32_t directions;  // which pair of directions: equal numbers, equal weights
        };
        Pending ring[kRing];
        alignas(32) float acc[3 * kMaxComponents];
        float mean[3];
        uint32_t directions = 0, accumulated = 0;
        AngularWeights vw, lw;
        Vec3 last_wi{NAN, NAN, NAN}, last_wo{NAN, NAN, NAN};
        const size_t n = queries.size();
        for (size_t i = 0; i < n + kAhead; ++i) {
            if (i >= kAhead) {
                const size_t q = i - kAhead;
                const Pending& p = ring[q % kRing];
                if (p.directions != accumulated) {
                    fused_angular<T>(p.vw, p.lw, acc, mean);
                    accumulated = p.directions;
                }
                out[q] = fused_value<T>(queries[q].uv, acc, mean);
            }
            if (i < n) {
                const Query& query = queries[i];
                if (!(query.wi.x == last_wi.x && query.wi.y == last_wi.y &&
                      query.wi.z == last_wi.z && query.wo.x == last_wo.x &&
                      query.wo.y == last_wo.y && query.wo.z == last_wo.z)) {
                    vw = views.weights(query.wo);
                    lw = light_lookup->weights(query.wi);
                    last_wi = query.wi;
                    last_wo = query.wo;
                    ++directions;
                    prefetch_angular<T>(vw, lw);
                }
                ring[i % kRing] = {vw, lw, directions};
                prefetch_bilinear<T>(query.uv);
            }
        }
    }

    template <typename T>
    void general_batch(std::span<const Query> queries, std::span<Rgb> out) const {
        // Angular accumulations cached per block for the current pair of directions.
        const int stride = channels * std::max(max_kp, kLanes);
        std::vector<float> cache(blocks.size() * stride);
        std::vector<float> cache_mean(blocks.size() * 3);
        std::vector<uint32_t> stamp(blocks.size(), 0);
        uint32_t current = 0;
        AngularWeights vw, lw;
        Vec3 last_wi{NAN, NAN, NAN}, last_wo{NAN, NAN, NAN};
        for (size_t q = 0; q < queries.size(); ++q) {
            const Query& query = queries[q];
            if (!(query.wi.x == last_wi.x && query.wi.y == last_wi.y && query.wi.z == last_wi.z &&
                  query.wo.x == last_wo.x && query.wo.y == last_wo.y && query.wo.z == last_wo.z)) {
                vw = views.weights(query.wo);
                lw = light_lookup->weights(query.wi);
                last_wi = query.wi;
                last_wo = query.wo;
                ++current;
            }
            out[q] = general_batch_value<T>(query.uv, vw, lw, cache.data(), cache_mean.data(),
                                            stamp.data(), current, stride);
        }
    }

    // eval_stochastic_batch() in three stages over groups of kGroup queries: the weights of group
    // g + 1 are looked up, group g draws its texels, views and lights from the weights looked up
    // one step earlier (kGroup queries at once, one per vector lane) and prefetches their rows,
    // and the queries kAhead before group g are evaluated from rows prefetched kAhead queries
    // earlier. Each stage waits only on an earlier step, so the processor overlaps the long
    // lookups and the long chains of picks of several queries.
    template <typename T>
    BTF_CLONES void stochastic_batch(std::span<const StochasticQuery> queries,
                                     std::span<Rgb> out) const {
        constexpr size_t kAhead = kAheadStochastic;
        static_assert(kAhead % kGroup == 0 && kAhead + kGroup <= kRing);
        Drawn ring[kRing];
        WeighedGroup weighed[2];
        double numbers[2][kGroup];
        const size_t n = queries.size();
        // A group's weights and numbers; lanes past the end look up the zenith, and their draws
        // are not read.
        static_assert(kGroup == 4);  // weights4()'s lanes
        const Vec3 zenith{0, 0, 1};
        auto weigh = [&](size_t first, WeighedGroup& w, double* u) {
            // The queries of a group some groups ahead: their lines come from memory.
            constexpr size_t kQueriesAhead = 8 * kGroup;
            if (first + kQueriesAhead < n) {
                const char* next = reinterpret_cast<const char*>(&queries[first + kQueriesAhead]);
                for (size_t b = 0; b < kGroup * sizeof(StochasticQuery); b += 64)
                    __builtin_prefetch(next + b);
            }
            std::array<const Vec3*, kGroup> wo, wi;
#pragma GCC unroll 4
            for (size_t j = 0; j < kGroup; ++j) {
                if (first + j >= n) {
                    w.lx[j] = w.ly[j] = {};
                    wo[j] = wi[j] = &zenith;
                    u[j] = 0;
                    continue;
                }
                const StochasticQuery& q = queries[first + j];
                w.lx[j] = wrap_lerp(q.uv.u, width);
                w.ly[j] = wrap_lerp(q.uv.v, height);
                wo[j] = &q.wo;
                wi[j] = &q.wi;
                u[j] = clamp_filter_number(q.u);
            }
            AngularInterpolator::weights4(views, wo, w.vw, *light_lookup, wi, w.lw);
        };
        const size_t groups = (n + kGroup - 1) / kGroup;
        if (groups > 0) weigh(0, weighed[0], numbers[0]);
        for (size_t g = 0; g < groups + kAhead / kGroup; ++g) {
            const size_t first = g * kGroup;
            if (g + 1 < groups) weigh(first + kGroup, weighed[(g + 1) % 2], numbers[(g + 1) % 2]);
            if (g < groups) {
                Drawn* d = ring + first % kRing;
                draw_group(weighed[g % 2], numbers[g % 2], d);
                for (size_t j = 0; j < kGroup; ++j)
                    prefetch_sample<T>(d[j].texel, d[j].view, d[j].light);
            }
            if (first >= kAhead)
                for (size_t q = first - kAhead; q < std::min(first - kAhead + kGroup, n); ++q) {
                    const Drawn& d = ring[q % kRing];
                    out[q] = finish(sample<T>(d.texel, d.view, d.light));
                }
        }
    }
};

FactorMaterial::FactorMaterial(Model model, RowStorage rows) : m_model(std::move(model)) {
    m_model.validate("factor model");
    m_impl = std::make_unique<Impl>(m_model, rows);
}

FactorMaterial::~FactorMaterial() = default;

int FactorMaterial::total_components() const {
    int total = 0;
    for (const Block& b : m_model.blocks) total += b.components();
    return total;
}

bool FactorMaterial::half_rows() const {
    return m_impl->half;
}

Rgb FactorMaterial::eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    const Impl& m = *m_impl;
    return m.half ? m.eval<uint16_t>(uv, wi, wo) : m.eval<float>(uv, wi, wo);
}

void FactorMaterial::eval_batch(std::span<const Query> queries, std::span<Rgb> out) const {
    if (queries.size() != out.size())
        fail("eval_batch: {} queries but {} outputs", queries.size(), out.size());
    const Impl& m = *m_impl;
    if (m.single_block()) {
        if (m.half)
            m.single_block_batch<uint16_t>(queries, out);
        else
            m.single_block_batch<float>(queries, out);
    } else {
        if (m.half)
            m.general_batch<uint16_t>(queries, out);
        else
            m.general_batch<float>(queries, out);
    }
}

Rgb FactorMaterial::eval_sample(int x, int y, int view, int light) const {
    if (x < 0 || y < 0 || x >= m_model.width || y >= m_model.height || view < 0 ||
        view >= m_model.sampling.num_views() || light < 0 || light >= m_model.sampling.num_lights())
        fail("eval_sample: ({}, {}, view {}, light {}) is outside the material", x, y, view, light);
    const Impl& m = *m_impl;
    const int64_t texel = int64_t(y) * m_model.width + x;
    return m.finish(m.half ? m.sample<uint16_t>(texel, view, light)
                           : m.sample<float>(texel, view, light));
}

// eval_sample() for each index, the rows of the index kAheadStochastic further prefetched (an
// uninterpolated sample reads as many lines as a stochastic query: the a and b rows of one
// sample).
void FactorMaterial::eval_sample_batch(std::span<const SampleIndex> indices,
                                       std::span<Rgb> out) const {
    if (indices.size() != out.size())
        fail("eval_sample_batch: {} indices but {} outputs", indices.size(), out.size());
    const Impl& m = *m_impl;
    const int width = m_model.width, height = m_model.height;
    const int views = m_model.sampling.num_views(), lights = m_model.sampling.num_lights();
    auto inside = [&](const SampleIndex& s) {
        return s.x >= 0 && s.y >= 0 && s.x < width && s.y < height && s.view >= 0 &&
               s.view < views && s.light >= 0 && s.light < lights;
    };
    auto run = [&]<typename T>() {
        for (size_t i = 0; i < indices.size(); ++i) {
            if (i + kAheadStochastic < indices.size()) {
                const SampleIndex& next = indices[i + kAheadStochastic];
                if (inside(next))
                    m.prefetch_sample<T>(int64_t(next.y) * width + next.x, next.view, next.light);
            }
            const SampleIndex& s = indices[i];
            if (!inside(s))
                fail("eval_sample_batch: ({}, {}, view {}, light {}) is outside the material", s.x,
                     s.y, s.view, s.light);
            out[i] = m.finish(m.sample<T>(int64_t(s.y) * width + s.x, s.view, s.light));
        }
    };
    if (m.half)
        run.template operator()<uint16_t>();
    else
        run.template operator()<float>();
}

Rgb FactorMaterial::eval_sample_reference(int x, int y, int view, int light) const {
    const Impl& m = *m_impl;
    const int64_t texel = int64_t(y) * m_model.width + x;
    return m.finish(m.half ? m.sample_reference<uint16_t>(texel, view, light)
                           : m.sample_reference<float>(texel, view, light));
}

Rgb FactorMaterial::eval_reference(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    const Impl& m = *m_impl;
    const Rgb planes = lookup6d(uv, m_model.width, m_model.height, m.views.weights(wo),
                                m.lights.weights(wi), [&](int x, int y, int view, int light) {
                                    const int64_t texel = int64_t(y) * m_model.width + x;
                                    return m.half ? m.sample_reference<uint16_t>(texel, view, light)
                                                  : m.sample_reference<float>(texel, view, light);
                                });
    return m.finish(planes);
}

Selection FactorMaterial::select(const Uv& uv, const Vec3& wo, double u) const {
    return m_impl->select(uv, wo, u);
}

Rgb FactorMaterial::eval_selected(const Selection& s, const Uv&, const Vec3&,
                                  const Vec3& wi) const {
    const Impl& m = *m_impl;
    const int light = m.pick_light(wi, s.u);
    const int64_t texel = int64_t(s.y) * m_model.width + s.x;
    return m.finish(m.half ? m.sample<uint16_t>(texel, s.view, light)
                           : m.sample<float>(texel, s.view, light));
}

void FactorMaterial::eval_stochastic_batch(std::span<const StochasticQuery> queries,
                                           std::span<Rgb> out) const {
    if (queries.size() != out.size())
        fail("eval_stochastic_batch: {} queries but {} outputs", queries.size(), out.size());
    const Impl& m = *m_impl;
    if (m.half)
        m.stochastic_batch<uint16_t>(queries, out);
    else
        m.stochastic_batch<float>(queries, out);
}

}  // namespace btf::factor
