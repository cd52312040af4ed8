// SPDX-License-Identifier: MIT
#pragma once
/// The multi-level vector quantization of §4.3–§4.4 (Havran, Filip, Myszkowski 2010): texels'
/// apparent BRDFs on the grid are matched against the code-books top down and, where no
/// code-vector is similar enough, decomposed into lower-dimensional slices until a match is found
/// or new data enter P1 and C.
///
/// Insertion of a texel's F_x (three planes Y, c₁, c₂ over the grid, raw values):
///   P4: the most similar code-vector within ε_P4 → (its index, c_P6 = Σ Y). Otherwise every φv
///       slice goes to P3, and the new P4 entry holds their indices and scales c_P4 = (Σ Y of the
///       slice) / (Σ Y of F_x); its code-vector is the reconstruction from those entries (what the
///       decoder will produce), so later texels are compared with what they would decode to.
///   P3: likewise over θv slices into M.
///   M:  a match within ε_M, or the luminance goes to P2 and the chromaticity to I2; the new M
///       entry is the pair (an existing identical pair is reused).
///   P2: likewise over α slices into P1; P1 keeps a new slice as it is (normalized).
///   I2 → I1 → C likewise for chromaticity (no scales).
/// Every level receives raw slices, so its threshold bounds the error in the planes' own units:
/// with measure mse the mean squared error of the reconstruction over the slice's values (all
/// three planes where it has them); the user's ε_P4 shrinks by level_factor per level below
/// (P3 f·ε, M f²·ε, P2 f³·ε, P1 f⁴·ε, §4.4.1), and the chromaticity levels have their own
/// thresholds. A decomposed slice's error is at most the largest of its children's thresholds
/// (its MSE is the mean of theirs), so f = 1 already keeps every texel within ε_P4; the paper's
/// f = 0.4 makes the lower code-books far larger for little gain. With measure mssim every level
/// takes the same threshold (§4.4.2).
///
/// Training (§5.1.1) is the caller's: insert() a Halton-sampled 1 % of the texels, scale the
/// thresholds by 2.5 and insert() 4 % more, then nearest() for the rest (frozen code-books).

#include <map>
#include <span>
#include <vector>

#include "btf/codecs/mlvq/codebooks.h"
#include "btf/codecs/mlvq/vq.h"

namespace btf::mlvq {

struct EncoderOptions {
    MlvqGrid grid;
    ColourModel colour = ColourModel::kYCbCr;
    Measure measure = Measure::mse;
    double threshold = 3e-5;     ///< ε_P4
    double level_factor = 1;     ///< mse: threshold ratio between successive luminance levels
    double threshold_i2 = 3e-5;  ///< chromaticity thresholds (mse; mssim uses `threshold`)
    double threshold_i1 = 3e-5;
    double threshold_c = 3e-5;
    SsimOptions ssim;
};

class Encoder {
  public:
    explicit Encoder(const EncoderOptions& options);

    /// Values of one texel's F_x: planes × grid samples, plane-major.
    size_t texel_length() const { return size_t(3 * m_options.grid.samples()); }

    /// Encodes one texel, growing the code-books; returns its P6 entry.
    IndexScale insert(std::span<const float> texel);
    /// The P6 entries of texels laid end to end: the most similar P4 code-vector of each (no
    /// threshold), in parallel, code-books unchanged.
    std::vector<IndexScale> nearest(std::span<const float> texels) const;
    /// Multiplies every threshold by `factor` (training step 2).
    void scale_thresholds(double factor);
    /// Prepares the code-books for nearest() (rebuilds the search indices).
    void freeze();

    /// The code-books as the decoder will hold them.
    const Codebooks& codebooks() const { return m_books; }
    /// Code-vectors per level, for progress and statistics.
    size_t size_p4() const { return m_books.size_p4(); }

  private:
    template <typename Child>
    uint32_t split(Codebook& book, const Codebook& children, std::vector<IndexScale>& table,
                   std::span<const float> query, int parts, Child child);
    uint32_t p4(const float* texel);                 // 3 × n4 raw values
    uint32_t p3(const float* slice, size_t stride);  // plane stride
    uint32_t merge(const float* slice, size_t stride);
    uint32_t p2(const float* y);
    uint32_t p1(const float* y);
    uint32_t i2(const float* c1, const float* c2);
    uint32_t i1(const float* c1, const float* c2);
    uint32_t c(float c1, float c2);

    EncoderOptions m_options;
    Codebooks m_books;
    Codebook m_p4, m_p3, m_m, m_p2, m_p1, m_i2, m_i1, m_c;
    std::map<std::array<uint32_t, 2>, uint32_t> m_pairs;  // M entries by (P2, I2)
};

}  // namespace btf::mlvq
