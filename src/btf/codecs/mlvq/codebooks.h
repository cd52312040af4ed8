// SPDX-License-Identifier: MIT
#pragma once
/// The code-books of the multi-level vector quantization codec `mlvq` (Havran, Filip, Myszkowski
/// 2010, §4.3, Fig. 3) as the decoder holds them, the reconstruction of equation 4, and their
/// storage (§4.5).
///
/// A texel's apparent BRDF F_x(α, β, θv, φv) on the grid of parametrization.h has three planes:
/// luminance Y (linear, ≥ 0) and two chromaticity planes (colour.h below). Luminance is a chain of
/// normalized slices with scales:
///
///     P6[x]                   → (index into P4, c_P6)                      per texel
///     P4[i4][φv]              → (index into P3, c_P4)                      nφv entries
///     P3[i3][θv]              → (index into M,  c_P3)                      nθv entries
///     M[iM]                   → (index into P2, index into I2)            the merge table
///     P2[i2][α]               → (index into P1, c_P2)                      nα entries
///     P1[i1][β]               → value (a slice normalized to unit sum)     nβ values
///     Y = c_P6 · c_P4 · c_P3 · c_P2 · P1(...)                              (equation 4)
///
/// and chromaticity a chain of indices without scales:
///
///     I2[iI2][α] → index into I1,   I1[iI1][β] → index into C,   C[iC] → (c₁, c₂).
///
/// Every level's function is normalized to unit luminance sum over its samples (a discrete PDF,
/// §4.2), so c_P2 of a P2 entry sum to 1 over α, and the scale of a slice is the luminance mass it
/// carries: what importance sampling reads (§5.2).
///
/// Interpolation (Fig. 6): a query's 2 × 2 × 2 × 2 neighbouring grid samples are each
/// reconstructed through the chain and blended with the lookup's multilinear weights, luminance
/// and chromaticity alike; the blend is converted to RGB afterwards.
///
/// Colour: LDR sources use YCbCr (BT.601 on btfkit's linear values: chromaticity planes Cb, Cr),
/// HDR sources LogLuv (Larson 1998: chromaticity u′, v′, which do not scale with intensity). In
/// both the luminance plane holds linear Y: the code-books are PDFs, and LogLuv's log2 is a
/// storage encoding of Y that the scalar quantization of the scales replaces (16-bit P2 scales
/// for HDR, §4.5).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <tuple>
#include <vector>

#include "btf/codecs/mlvq/parametrization.h"
#include "btf/core/math.h"
#include "btf/io/package.h"
#include "btf/util/error.h"
#include "btf/util/json_fields.h"

namespace btf::mlvq {

enum class ColourModel { kYCbCr, kLogLuv };
std::string to_string(ColourModel model);
/// "ycbcr" or "logluv"; throws btf::Error otherwise.
ColourModel parse_colour_model(const std::string& text);

/// RGB → (Y, chroma 1, chroma 2) and back.
std::array<float, 3> to_planes(ColourModel model, const Rgb& rgb);
Rgb from_planes(ColourModel model, float y, float c1, float c2);

/// An index into the next code-book and a scale.
struct IndexScale {
    uint32_t index = 0;
    float scale = 0;
    bool operator==(const IndexScale&) const = default;
};

struct Codebooks {
    MlvqGrid grid;
    ColourModel colour = ColourModel::kYCbCr;
    // Luminance.
    std::vector<float> p1;                   ///< S1 × nβ
    std::vector<IndexScale> p2;              ///< S2 × nα, into P1
    std::vector<std::array<uint32_t, 2>> m;  ///< SM: (into P2, into I2)
    std::vector<IndexScale> p3;              ///< S3 × nθv, into M
    std::vector<IndexScale> p4;              ///< S4 × nφv, into P3
    // Chromaticity.
    std::vector<std::array<float, 2>> c;  ///< SC
    std::vector<uint32_t> i1;             ///< SI1 × nβ, into C
    std::vector<uint32_t> i2;             ///< SI2 × nα, into I1

    size_t size_p1() const { return p1.size() / size_t(grid.n_beta); }
    size_t size_p2() const { return p2.size() / size_t(grid.n_alpha); }
    size_t size_m() const { return m.size(); }
    size_t size_p3() const { return p3.size() / size_t(grid.n_theta_v); }
    size_t size_p4() const { return p4.size() / size_t(grid.n_phi_v); }
    size_t size_c() const { return c.size(); }
    size_t size_i1() const { return i1.size() / size_t(grid.n_beta); }
    size_t size_i2() const { return i2.size() / size_t(grid.n_alpha); }

    /// Throws btf::Error naming `what` and the first index out of range or non-finite value.
    void validate(const std::string& what) const;

    /// Planes (Y, c₁, c₂) of grid sample (φv m, θv k, α i, β j) of the function P4[p6.index]
    /// scaled by p6.scale.
    std::array<float, 3> sample(const IndexScale& p6, int m, int k, int i, int j) const;
};

/// One material of a package: its extent, sampling, and planar index P6 (per texel,
/// y · width + x; entries of texels not yet received are copies of a coarser neighbour's, see
/// mlvq.cpp).
struct TexelIndex {
    std::string name;
    int width = 0, height = 0;
    Sampling sampling;
    bool hdr = false;
    std::vector<IndexScale> p6;
};

/// A quantizer's header fields: its range [lo, hi] under the keys given (finite numbers, lo ≤ hi)
/// and its `bits`, 8 or 16.
struct QuantizerFields {
    double lo = 0, hi = 0;
    int bits = 8;
};
inline QuantizerFields quantizer_fields(const nlohmann::json& j, std::string_view lo_key,
                                        std::string_view hi_key) {
    const QuantizerFields q{json_fields::number_at(j, lo_key, -1e30, 1e30),
                            json_fields::number_at(j, hi_key, -1e30, 1e30),
                            int(json_fields::integer_at(j, "bits", 8, 16))};
    if (q.bits != 8 && q.bits != 16) fail("quantization with {} bits", q.bits);
    if (q.hi < q.lo) fail("quantization range [{}, {}]", q.lo, q.hi);
    return q;
}

/// Linear scalar quantization to `bits` bits over [lo, hi] (§4.5): how a package stores P1 and C
/// values, and the codes the evaluator keeps for C.
struct LinearQuantizer {
    float lo = 0, hi = 0;
    int bits = 8;
    static LinearQuantizer fit(const float* v, size_t n, int bits) {
        LinearQuantizer q;
        q.bits = bits;
        if (n == 0) return q;
        q.lo = *std::min_element(v, v + n);
        q.hi = *std::max_element(v, v + n);
        return q;
    }
    uint32_t max_code() const { return (1u << bits) - 1; }
    uint32_t encode(float x) const {
        if (!(hi > lo)) return 0;
        const double t = (double(x) - lo) / (double(hi) - lo) * max_code();
        return uint32_t(std::clamp(std::lround(t), 0l, long(max_code())));
    }
    float decode(uint32_t code) const {
        if (!(hi > lo)) return lo;
        return float(lo + (double(hi) - lo) * code / max_code());
    }
    nlohmann::json json() const { return {{"lo", lo}, {"hi", hi}, {"bits", bits}}; }
    static LinearQuantizer from(const nlohmann::json& j) {
        const QuantizerFields f = quantizer_fields(j, "lo", "hi");
        return {float(f.lo), float(f.hi), f.bits};
    }
};

/// Bytes of the code-books and the P6 of `texels` texels in the four representations of the
/// paper's Table 2: C.R.1 32-bit indices and floats; C.R.2 indices of ⌈log2 S⌉ bits, 32-bit
/// floats; C.R.3 32-bit indices, 8-bit floats (16-bit P2 scales for HDR); C.R.4 both compact
/// (what btfkit stores).
struct StorageSizes {
    std::array<int64_t, 4> bytes{};
    /// Per code-book (P1, P2, M, P3, P4, C, I1, I2, P6): entries and bytes in C.R.4's form.
    std::vector<std::tuple<std::string, int64_t, int64_t>> books;
};
StorageSizes storage_sizes(const Codebooks& books, int64_t texels, bool hdr);

/// Bits of an index into a code-book of n entries: ⌈log2 n⌉ (0 for n ≤ 1).
int index_bits(size_t n);

/// The package sections of the code-books ("codebooks") and the JSON header fields describing
/// them (sizes, quantization ranges), scalar-quantized (§4.5: 8 bits per value, 16 for the P2
/// scales when `hdr`) with compact indices.
void write_codebooks(const Codebooks& books, bool hdr, nlohmann::json& header,
                     std::vector<PackageSection>& sections);
/// The inverse; throws btf::Error for inconsistent headers or section sizes.
Codebooks read_codebooks(const Package& package);

/// The P6 of one material as sections "<prefix>P6.<level>" (level L … 0: texels on the
/// 2^level grid not on a coarser one), scales quantized to 8 bits against [lo, hi] written to
/// `header`, indices in ⌈log2 S4⌉ bits.
void write_texel_index(const TexelIndex& index, size_t size_p4, const std::string& prefix,
                       nlohmann::json& header, std::vector<PackageSection>& sections);
/// The inverse for the sections present (a prefix): absent texels copy the nearest present
/// texel of the coarser levels. Throws btf::Error when no level is present.
std::vector<IndexScale> read_texel_index(const Package& package, const nlohmann::json& header,
                                         const std::string& prefix, int width, int height,
                                         size_t size_p4);
/// The levels of a texel index of an extent (coarsest first in the stream).
int texel_index_levels(int width, int height);

}  // namespace btf::mlvq
