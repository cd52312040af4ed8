// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/decoded.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "btf/util/error.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

#if defined(__AVX2__) && defined(__F16C__)
#include <immintrin.h>
#define BTF_MLVQ_SIMD 1
#endif

namespace btf::mlvq {

DecodedBooks::DecodedBooks(const Codebooks& b) : m_grid(b.grid) {
    const MlvqGrid& g = m_grid;
    const int n_views = g.n_phi_v * g.n_theta_v;
    m_per_entry = size_t(tiles(g.n_alpha)) * size_t(tiles(g.n_beta)) * kTile * kTile;
    // The row integrals, the halves, and the window of the last row's read; whole lines.
    const size_t masses = (size_t(g.n_alpha) + 1) * sizeof(float);
    const size_t last_row = masses + sizeof(uint16_t) * size_t(g.n_alpha - 1) * size_t(g.n_beta);
    const size_t bytes = std::max(masses + sizeof(uint16_t) * size_t(g.n_alpha) * size_t(g.n_beta),
                                  last_row + kRowWindow);
    m_record_floats = (bytes + 63) / 64 * (64 / sizeof(float));

    // P4 ∘ P3.
    m_views.resize(b.size_p4() * size_t(n_views));
    for (size_t e4 = 0; e4 < b.size_p4(); ++e4)
        for (int p = 0; p < g.n_phi_v; ++p) {
            const IndexScale& s4 = b.p4[e4 * g.n_phi_v + p];
            for (int t = 0; t < g.n_theta_v; ++t) {
                const IndexScale& s3 = b.p3[size_t(s4.index) * g.n_theta_v + t];
                m_views[(e4 * g.n_phi_v + p) * g.n_theta_v + t] = {s3.index, s4.scale * s3.scale};
            }
        }

    // C's codes: 8 bits per channel over its range, as write_codebooks() quantizes it.
    std::vector<std::array<uint8_t, 2>> codes(b.size_c());
    for (int ch = 0; ch < 2; ++ch) {
        std::vector<float> values(b.size_c());
        for (size_t i = 0; i < b.size_c(); ++i) values[i] = b.c[i][ch];
        const LinearQuantizer q = LinearQuantizer::fit(values.data(), values.size(), 8);
        m_chroma_lo[ch] = q.lo;
        m_chroma_step[ch] = (q.hi - q.lo) / float(q.max_code());
        for (size_t i = 0; i < b.size_c(); ++i) codes[i][ch] = uint8_t(q.encode(values[i]));
    }

    // M entries: luminance c_P2 · P1 and chromaticity I2 → I1 → C per (α, β) sample.
    // A package's M code-book is bounded by its section's size, its decoded tiles and sampling
    // records (1 KiB + 320 bytes per entry at the paper's grid) by the allocation limit.
    const size_t per_entry_bytes = m_per_entry * sizeof(Sample) + m_record_floats * sizeof(float);
    check_alloc(checked_bytes(b.size_m(), per_entry_bytes).value_or(UINT64_MAX), "mlvq code-books",
                fmt::format("decoding the {} entries of M", b.size_m()));
    m_samples.resize(b.size_m() * m_per_entry);
    parallel_for(0, int64_t(b.size_m()), [&](int64_t e) {
        const std::array<uint32_t, 2>& merge = b.m[size_t(e)];
        Sample* out = m_samples.data() + size_t(e) * m_per_entry;
        const int tiles_alpha = tiles(g.n_alpha), tiles_beta = tiles(g.n_beta);
        for (int i = 0; i < g.n_alpha; ++i) {
            const IndexScale& e2 = b.p2[size_t(merge[0]) * g.n_alpha + i];
            const float* slice = b.p1.data() + size_t(e2.index) * g.n_beta;
            const uint32_t* chroma =
                b.i1.data() + size_t(b.i2[size_t(merge[1]) * g.n_alpha + i]) * g.n_beta;
            for (int j = 0; j < g.n_beta; ++j) {
                const std::array<uint8_t, 2>& c = codes[chroma[j]];
                const Sample value = {Eigen::half_impl::float_to_half_rtne(e2.scale * slice[j]).x,
                                      {c[0], c[1]}};
                // Into every tile that holds it (up to 2 × 2 where tiles overlap).
                for (int ta = std::max(0, (i - 1) / kTileStep); ta < tiles_alpha; ++ta) {
                    const int r = i - kTileStep * ta;
                    if (r < 0) break;
                    if (r >= kTile) continue;
                    for (int tb = std::max(0, (j - 1) / kTileStep); tb < tiles_beta; ++tb) {
                        const int q = j - kTileStep * tb;
                        if (q < 0) break;
                        if (q >= kTile) continue;
                        out[((ta * tiles_beta + tb) * kTile + r) * kTile + q] = value;
                    }
                }
            }
        }
    });

    // Sampling records: the row integrals over β of each entry's luminance (trapezoid in
    // sample-index units) and their integral over α, what importance sampling picks rows and
    // components with, then the luminance halves row by row.
    m_records.resize(b.size_m() * m_record_floats);
    parallel_for(0, int64_t(b.size_m()), [&](int64_t e) {
        float* r = m_records.data() + size_t(e) * m_record_floats;
        char* halves = reinterpret_cast<char*>(r + g.n_alpha + 1);
        double total = 0;
        for (int i = 0; i < g.n_alpha; ++i) {
            double sum = 0;
            for (int j = 0; j < g.n_beta; ++j) {
                const Sample& s = sample(uint32_t(e), i, j);
                std::memcpy(halves + sizeof(uint16_t) * (size_t(i) * g.n_beta + j), &s.y, 2);
                const double y = luminance(s);
                sum += (j == 0 || j == g.n_beta - 1) ? 0.5 * y : y;
            }
            r[i] = float(sum);
            total += (i == 0 || i == g.n_alpha - 1) ? 0.5 * sum : sum;
        }
        r[g.n_alpha] = float(total);
    });
}

DecodedBooks::Corners::Corners(const MlvqGrid& g, const MlvqWeights& lw) {
    off[0] = offset(g, lw.alpha.index[0], lw.beta.index[0]);
    off[1] = off[0] + kTile;  // row α + 1 of the same tile
    for (int a = 0; a < 2; ++a)
        for (int q = 0; q < 2; ++q) w[a][q] = lw.alpha.weight[a] * lw.beta.weight[q];
}

std::array<float, 3> DecodedBooks::blend(const Sample* const* entries, const float* y_scale,
                                         const float* c_weight, int count, const Corners& k) const {
    float y = 0, c1 = 0, c2 = 0, c_total = 0;
#ifdef BTF_MLVQ_SIMD
    // The two α rows' sample pairs (16 bytes: 4 × (half Y, code c₁, code c₂)) shuffled into the
    // four halves of Y and the eight chroma codes.
    const __m128i shuffle = _mm_setr_epi8(0, 1, 4, 5, 8, 9, 12, 13, 2, 3, 6, 7, 10, 11, 14, 15);
    const __m128 wy = _mm_setr_ps(k.w[0][0], k.w[0][1], k.w[1][0], k.w[1][1]);
    const __m256 wc = _mm256_setr_ps(k.w[0][0], k.w[0][0], k.w[0][1], k.w[0][1], k.w[1][0],
                                     k.w[1][0], k.w[1][1], k.w[1][1]);
    __m128 acc_y = _mm_setzero_ps();
    __m256 acc_c = _mm256_setzero_ps();
    for (int c = 0; c < count; ++c) {
        int64_t row0, row1;
        std::memcpy(&row0, entries[c] + k.off[0], 8);
        std::memcpy(&row1, entries[c] + k.off[1], 8);
        const __m128i v = _mm_shuffle_epi8(_mm_set_epi64x(row1, row0), shuffle);
        acc_y = _mm_fmadd_ps(_mm_mul_ps(wy, _mm_set1_ps(y_scale[c])), _mm_cvtph_ps(v), acc_y);
        const __m256 codes = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_unpackhi_epi64(v, v)));
        acc_c = _mm256_fmadd_ps(_mm256_mul_ps(wc, _mm256_set1_ps(c_weight[c])), codes, acc_c);
        c_total += c_weight[c];
    }
    alignas(32) float ly[4], lc[8];
    _mm_store_ps(ly, acc_y);
    _mm256_store_ps(lc, acc_c);
    y = (ly[0] + ly[1]) + (ly[2] + ly[3]);
    c1 = (lc[0] + lc[2]) + (lc[4] + lc[6]);
    c2 = (lc[1] + lc[3]) + (lc[5] + lc[7]);
#else
    for (int c = 0; c < count; ++c)
        for (int a = 0; a < 2; ++a)
            for (int q = 0; q < 2; ++q) {
                const Sample& s = entries[c][k.off[a] + q];
                y += y_scale[c] * k.w[a][q] * luminance(s);
                c1 += c_weight[c] * k.w[a][q] * s.chroma[0];
                c2 += c_weight[c] * k.w[a][q] * s.chroma[1];
            }
    for (int c = 0; c < count; ++c) c_total += c_weight[c];
#endif
    // The codes are linear: Σ w (lo + step · code) = lo Σ w + step Σ w · code (the corner
    // weights of an entry sum to 1).
    return {y, m_chroma_lo[0] * c_total + m_chroma_step[0] * c1,
            m_chroma_lo[1] * c_total + m_chroma_step[1] * c2};
}

}  // namespace btf::mlvq
