// SPDX-License-Identifier: MIT
#pragma once
/// mlvq: multi-level vector quantization (Havran, Filip, Myszkowski 2010); see mlvq.cpp for the
/// user documentation, codebooks.h for the model and encoder.h for the quantization.

#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/mlvq/codebooks.h"
#include "btf/codecs/mlvq/decoded.h"
#include "btf/codecs/mlvq/encoder.h"

namespace btf {

/// The registry entry.
const Codec& mlvq_codec();

namespace mlvq {

class MlvqMaterial;

struct Options {
    EncoderOptions encoder;
    /// The colour model; none: auto, YCbCr for LDR sources and LogLuv for HDR ones.
    std::optional<ColourModel> colour;
    double first_fraction = 0.01;   ///< training step 1: Halton-sampled texels at the threshold
    double second_fraction = 0.04;  ///< training step 2, thresholds × growth
    double growth = 2.5;
    /// Bytes of raw and resampled texels held at once while reading the source in row bands.
    int64_t memory_bytes = int64_t(1) << 30;
};

/// Reads the options from codec parameters; checks ranges and reports unknown parameters.
Options parse_options(const Params& params);

/// Encoding statistics.
struct EncodeReport {
    int64_t trained = 0;  ///< texels inserted in steps 1 and 2
    int64_t texels = 0;
    double seconds_reading = 0, seconds_training = 0, seconds_frozen = 0;
};

/// Code-books shared by several materials (§5.1, Table 2 C.R.5) and the P6 of each: training
/// steps 1 and 2 insert the Halton texels of every material, then each material's other texels
/// take their nearest P4 entries. All code-books are shared (the paper shares the luminance
/// ones; sharing P4, P3 and M as well lets similar materials reuse whole apparent BRDFs). The
/// colour model is LogLuv when any source is HDR (colour=auto).
std::pair<Codebooks, std::vector<TexelIndex>> encode_shared(
    std::span<const BtfSource* const> sources, const Options& options,
    Progress& progress = Progress::none(), EncodeReport* report = nullptr);

/// A package of code-books and materials (one, or several sharing the code-books).
Package to_package(const Codebooks& books, const std::vector<TexelIndex>& materials,
                   const Options& options);
/// Every material of a package (or a clean prefix: the code-books and at least the coarsest P6
/// level of a material; materials whose P6 has not arrived are left out). Throws btf::Error
/// naming the problem for malformed packages.
std::vector<std::unique_ptr<MlvqMaterial>> open_all(const Package& package);

/// The code-books and P6 of `source`.
std::pair<Codebooks, TexelIndex> encode(const BtfSource& source, const Options& options,
                                        Progress& progress = Progress::none(),
                                        EncodeReport* report = nullptr);

/// The four texels of a bilinear lookup (wrapping) and their weights.
struct TexelCorners {
    int64_t texel[4];
    float weight[4];
};

/// A material decoded from code-books and its P6.
class MlvqMaterial final : public Material {
  public:
    /// `decoded`: the code-books' evaluation form, when several materials share them (built
    /// here otherwise).
    MlvqMaterial(std::shared_ptr<const Codebooks> books, TexelIndex index,
                 std::shared_ptr<const DecodedBooks> decoded = nullptr);

    int width() const override { return m_index.width; }
    int height() const override { return m_index.height; }
    const Sampling& sampling() const override { return m_index.sampling; }
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override;
    Rgb eval_sample(int x, int y, int view, int light) const override;
    /// eval() for many queries; consecutive queries with the same directions share one lookup.
    void eval_batch(std::span<const Query> queries, std::span<Rgb> out) const override;

    /// Importance sampling from the code-books (§5.2): the light function of a query is a
    /// mixture of ≤ 16 decoded M entries (4 texels × 2 θv × 2 φv, with their interpolation
    /// weights and scales), each bilinear in (α, u = sin β) — an equal-area parametrization, so
    /// a density over (α, u) is a density per solid angle. A component is picked by its mass,
    /// then α by the inverse CDF of the piecewise-linear marginal (the P2 row masses) and u by
    /// that of the conditional (the P1 slices of the two neighbouring rows), both solved exactly
    /// per segment. The pdf is the model's luminance over its integral: exactly proportional to
    /// what eval() returns as Y. Continuous in ξ2, and in ξ1 within each mixture component.
    /// A texel of zero luminance samples the hemisphere uniformly.
    LightSample sample(const Uv& uv, const Vec3& wo, double xi1, double xi2) const override;
    /// sample() for a batch, with the memory accesses of a group of queries overlapped.
    void sample_batch(std::span<const SampleQuery> queries,
                      std::span<LightSample> out) const override;
    double pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const override;
    /// (1/π) ∫ value dωi from the decoded M entries' integrals: exact for the model with YCbCr
    /// (linear in Y, Cb, Cr), a quadrature over the grid's light samples with LogLuv.
    Rgb albedo(const Uv& uv, const Vec3& wo) const override;
    bool native_sampling() const override { return true; }

    /// The stochastic filter (material.h) over mlvq's own interpolation: eval() blends 4 texels ×
    /// 2 θv × 2 φv view nodes of the grid, not the sampled views, so a shading point draws one
    /// texel and one view node with probability equal to its weight in eval() (select()), and
    /// its term reads one P6 → P4 ∘ P3 → M chain, bilinear in (α, β) within that M entry
    /// (eval_selected()). Its mean over u is eval() with YCbCr colour (linear in the planes);
    /// with LogLuv it is the mean of decoded terms, which differs from eval()'s one decoding of
    /// blended planes (docs/codecs.md). Sampling draws from that one entry's luminance, as
    /// sample() draws from a component of its mixture, and reports its value and pdf at the drawn
    /// (α, u), which eval_selected() and pdf_selected() of the drawn direction give back to within
    /// rounding (as sample() and pdf() do). These batches pipeline the stages of many queries,
    /// prefetching each level of the chain a stage ahead; the results equal ShadingPoint's, bit
    /// for bit. One thread, random queries, 256² woven_fabric at the default grid: 6–9 M/s
    /// evaluated and 4.9–5.9 M/s sampled, against 1.3–1.4 M/s for sample_batch (docs/
    /// benchmarks.md).
    void eval_stochastic_batch(std::span<const StochasticQuery> queries,
                               std::span<Rgb> out) const override;
    void sample_stochastic_batch(std::span<const StochasticSampleQuery> queries,
                                 std::span<LightSample> out) const override;

    const Codebooks& codebooks() const { return *m_books; }
    const TexelIndex& texel_index() const { return m_index; }
    const DecodedBooks& decoded() const { return *m_decoded; }
    /// Planes (Y, c₁, c₂) of texel (x, y) at the lookup weights w.
    std::array<float, 3> planes(int64_t texel, const MlvqWeights& w) const;

  protected:
    /// Selection::view of an mlvq shading point is its view node m · nθv + k (φv sample m, θv
    /// sample k): the offset of the node's (M entry, scale) among a P4 entry's fused views
    /// (DecodedBooks::views()). (x, y) is the texel; Selection::u is not used, the term being
    /// deterministic in the light direction.
    Selection select(const Uv& uv, const Vec3& wo, double u) const override;
    Rgb eval_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                      const Vec3& wi) const override;
    LightSample sample_selected(const Selection& s, const Uv& uv, const Vec3& wo, double xi1,
                                double xi2) const override;
    double pdf_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                        const Vec3& wi) const override;

  private:
    struct Gathered;
    void gather(const TexelCorners& corners, const MlvqWeights& w, Gathered& out) const;
    void prefetch_views(const TexelCorners& corners, const MlvqWeights& w) const;
    std::array<float, 3> combine(const Gathered& g) const;
    Rgb eval_weights(const Uv& uv, const MlvqWeights& w) const;

    std::shared_ptr<const Codebooks> m_books;
    TexelIndex m_index;
    /// P6 → (P4 ∘ P3) → M entries decoded to (α, β) samples, shared by every material of the
    /// code-books (decoded.h).
    std::shared_ptr<const DecodedBooks> m_decoded;

    struct Mixture;
    struct SampleState;
    void sample_begin(const SampleQuery& q, SampleState& s) const;
    void sample_mixture(SampleState& s) const;
    void sample_alpha(SampleState* states, size_t count) const;
    void sample_beta(SampleState* states, size_t count) const;
    void sample_finish(SampleState& s) const;

    /// The selections of count ≤ kPickLanes queries (query i: queries[i].uv, view[i],
    /// queries[i].u), their picks in the lanes of pick_lanes(); select() runs it with one.
    template <typename Query>
    void select_views(const Query* queries, const ViewLookup* view, size_t count,
                      Selection* out) const;
    void gather_selected(const Selection& s, Gathered& out) const;
    DecodedBooks::Corners light_corners(const Vec3& wi, const Vec3& wo) const;
    void sample_selected_begin(const Selection& s, const Uv& uv, const Vec3& wo,
                               const ViewLookup& view, double xi1, double xi2,
                               SampleState& out) const;
};

}  // namespace mlvq
}  // namespace btf
