// SPDX-License-Identifier: MIT
#pragma once
/// The code-books of an mlvq package as the evaluator and the sampler read them: built once per
/// Codebooks and shared by every material that uses them.
///
/// Evaluation follows P6 → P4 → P3 → M → (P2 → P1, I2 → I1 → C) for each of a query's 4 texels ×
/// 2 φv × 2 θv, and a random query touches a random part of every code-book. Walking the chain as
/// stored costs seven dependent memory reads per corner; the decoded form has two levels:
///
///  - views: P4 and P3 fused, (P4 entry, φv, θv) → (M entry, c_P4 · c_P3);
///  - entries: each M entry's 2-D light function on the (α, β) grid, 4 bytes per sample: the
///    luminance c_P2 · P1 as an IEEE half (relative error ≤ 2⁻¹¹, below the 8-bit storage of P1)
///    and the chromaticity I2 → I1 → C as its two 8-bit codes (exactly what a package stores; the
///    codes are linear, so they are blended first and converted once). The samples lie in tiles
///    of 4 × 4 that overlap their neighbours by one sample (64 bytes, a cache line each): the
///    2 × 2 (α, β) corners of every lookup lie in one tile, so a random lookup reads one line of
///    an entry (rows of 11 samples put them on two lines in about three lookups of four), and the
///    16 prefetches of a query fit the core's miss buffers (at nα = nβ = 11 an entry takes 4 × 4
///    tiles, 1024 bytes, against 484 untiled: 2.1× the memory for 1.7× fewer lines per lookup).
///    The corners are two 8-byte reads, one per α row, that one SIMD shuffle decodes;
///
/// plus, per entry, a record of what importance sampling reads: the row integrals and the
/// luminance once more, untiled (sampling reads two whole α rows, which cross every tile of a tile
/// row: four lines, against one or two here; 320 bytes an entry at the paper's grid).

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <vector>

#include "btf/codecs/mlvq/codebooks.h"
#include "btf/util/huge_pages.h"

#ifdef __F16C__
#include <immintrin.h>
#endif

namespace btf::mlvq {

class DecodedBooks {
  public:
    /// Chromaticity codes are fitted to C's range per channel (8 bits, as a package stores them:
    /// exact for code-books read from a package).
    explicit DecodedBooks(const Codebooks& books);

    struct Sample {
        uint16_t y;         ///< luminance, IEEE half bits
        uint8_t chroma[2];  ///< chromaticity codes
    };

    /// A query's 2 × 2 (α, β) corners within an entry: samples off[a] and off[a] + 1 of each α
    /// row a (β neighbours are adjacent: the β axis is clamped, not periodic) and their weights
    /// w[a][q].
    struct Corners {
        int off[2] = {0, 0};
        float w[2][2] = {};
        Corners() = default;
        Corners(const MlvqGrid& g, const MlvqWeights& lw);
    };
    /// Σ_c y_scale[c] · Y_c and Σ_c c_weight[c] · (c₁, c₂)_c over `count` entries, Y_c and
    /// (c₁, c₂)_c the entries' values blended over the corners.
    std::array<float, 3> blend(const Sample* const* entries, const float* y_scale,
                               const float* c_weight, int count, const Corners& corners) const;

    const MlvqGrid& grid() const { return m_grid; }
    /// (M entry, c_P4 · c_P3) of P4 entry `p4` at view sample (φv, θv).
    const IndexScale& view(uint32_t p4, int phi_v, int theta_v) const {
        return m_views[(size_t(p4) * m_grid.n_phi_v + phi_v) * m_grid.n_theta_v + theta_v];
    }
    /// Address of the same, for prefetching.
    const IndexScale* views(uint32_t p4) const {
        return m_views.data() + size_t(p4) * m_grid.n_phi_v * m_grid.n_theta_v;
    }
    /// Tiles per axis of n samples: tile t holds samples 3t … 3t + 3 (kTile = 4, overlapping
    /// its neighbours by one), so that every window (i, i + 1), i ≤ n − 2, lies in tile i / 3.
    static constexpr int kTile = 4, kTileStep = 3;
    static int tiles(int n) { return (n - 2) / kTileStep + 1; }
    /// The tile of an axis of `tiles` tiles that holds the window at sample i (the last one for
    /// the axis's last sample).
    static int tile_of(int i, int tiles) { return std::min(i / kTileStep, tiles - 1); }
    /// Offset of sample (i, j) within an entry, in the tile that holds the window at (i, j) (or
    /// the last tile of an axis); sample (i + 1, j) is kTile further (the next row of the tile).
    static int offset(const MlvqGrid& g, int i, int j) {
        const int tiles_beta = tiles(g.n_beta);
        const int a = tile_of(i, tiles(g.n_alpha)), b = tile_of(j, tiles_beta);
        return ((a * tiles_beta + b) * kTile + i - kTileStep * a) * kTile + j - kTileStep * b;
    }
    /// The samples of M entry `m`: tiles of 4 × 4 (α, β) samples (64 bytes, a cache line),
    /// α-major; offset() finds a sample.
    const Sample* entry(uint32_t m) const { return m_samples.data() + size_t(m) * m_per_entry; }
    const Sample& sample(uint32_t m, int i, int j) const { return entry(m)[offset(m_grid, i, j)]; }
    /// Entry m's sampling record (64-byte aligned; record_floats() floats): the row integrals
    /// of its luminance over β (trapezoid, sample-index units) for each α and their integral
    /// over α (nα + 1 floats; the first line at the paper's grid), then the luminance samples
    /// as IEEE halves, α-major (nα × nβ, packed two to a float's bytes), then padding to whole
    /// lines that holds the kRowWindow bytes from every row's start: what a draw from the entry
    /// reads, in 5 lines at the paper's grid. rows(m) is its start, the integrals.
    const float* record(uint32_t m) const { return m_records.data() + size_t(m) * m_record_floats; }
    const float* rows(uint32_t m) const { return record(m); }
    size_t record_floats() const { return m_record_floats; }
    /// Bytes from a row's first half that a reader may load at once (16 halves: one vector),
    /// all within the record.
    static constexpr size_t kRowWindow = 32;
    /// The bytes of the halves of α row i of entry m's record (nβ of them; row i + 1 follows),
    /// for loads that do not care for types (vector loads, memcpy): luminance_at() reads one.
    const void* luminance_row(uint32_t m, int i) const {
        return reinterpret_cast<const char*>(record(m) + m_grid.n_alpha + 1) +
               sizeof(uint16_t) * size_t(i) * size_t(m_grid.n_beta);
    }
    static float luminance_at(const void* row, int j) {
        Sample s{};
        std::memcpy(&s.y, static_cast<const char*>(row) + sizeof(uint16_t) * size_t(j), 2);
        return luminance(s);
    }
    size_t size_m() const { return m_per_entry ? m_samples.size() / m_per_entry : 0; }
    /// Bytes of the decoded entries (tiles and sampling records) and of the fused views.
    size_t entry_bytes() const {
        return m_samples.size() * sizeof(Sample) + m_records.size() * sizeof(float);
    }
    size_t view_bytes() const { return m_views.size() * sizeof(IndexScale); }

    static float luminance(const Sample& s) {
#ifdef __F16C__
        return _cvtsh_ss(s.y);  // one instruction; Eigen's portable conversion takes a dozen
#else
        return Eigen::half_impl::half_to_float(Eigen::half_impl::raw_uint16_to_half(s.y));
#endif
    }
    std::array<float, 2> chroma(const Sample& s) const {
        return {m_chroma_lo[0] + m_chroma_step[0] * s.chroma[0],
                m_chroma_lo[1] + m_chroma_step[1] * s.chroma[1]};
    }

  private:
    MlvqGrid m_grid;
    size_t m_per_entry = 0;
    // Tables read at random (on huge pages where large: huge_pages.h).
    std::vector<IndexScale, TableAllocator<IndexScale>> m_views;
    std::vector<Sample, TableAllocator<Sample>> m_samples;
    float m_chroma_lo[2] = {0, 0}, m_chroma_step[2] = {0, 0};
    size_t m_record_floats = 0;
    std::vector<float, TableAllocator<float>> m_records;
};

}  // namespace btf::mlvq
