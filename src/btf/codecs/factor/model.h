// SPDX-License-Identifier: MIT
#pragma once
/// The linear factor model shared by the factorization codecs (fmf, pca-views, lpca, perceptual):
/// its package sections, its quantization and its fast evaluator.
///
/// The BTF is split into blocks by colour plane, view group and texel cluster. Each block is one
/// factorized matrix whose rows are angular samples and whose columns are the block's texels:
///
///     row = (slot · nL + light) · channels + channel     (slot = position of the view in its
///     group) value(row, texel) = mean[row] + Σ_k a(row, k) · b(texel, k)
///
/// - `fmf`: one group of all views, one cluster; rgb colour (channels = 3, one plane) or
///   decorrelated colour (channels = 1, three planes).
/// - `pca-views`: groups of k neighbouring views, one cluster, rows centred on their mean.
/// - `lpca`: one group, texels clustered by their ABRDF, rows centred per cluster.
/// - `perceptual`: one group, one cluster, CIELab planes; with high-frequency omission several
///   spatial levels, each block's texel factor b at its level's resolution.
///
/// Colour: plane values are p = T · f(rgb), with f = identity or f(x) = log(x + eps) (dynamic
/// range reduction) and T the identity (rgb) or an orthonormal luminance/chroma basis
/// (decorrelated), or the nonlinear model11 and CIELab conversions; decoding inverts them after
/// the linear combination. Interpolation (bilinear in space, barycentric over views and lights)
/// happens on the plane values.
///
/// Spatial levels: a block of level j stores b on a grid of (width / 2^j) × (height / 2^j) texels;
/// the model's value at texel (x, y) is the bilinear, wrapping up-sampling of that grid, whose
/// texel centres lie at ((i + 0.5) · 2^j − 0.5) in full-resolution texel units. Levels need one
/// texel cluster and width and height divisible by 2^(levels − 1).
///
/// Angular levels: a block of angular level m ≥ 1 stores a on the directions of
/// angular_levels[m − 1] (views × lights of that subset, rows (view' · nL' + light') · channels +
/// channel); its value at every (view, light) is the up-sampling U of angular_levels.h, applied
/// once when a FactorMaterial is built. Angular levels need one view group holding the views in
/// order, and such blocks have no row means.

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/angular_levels.h"
#include "btf/codecs/factor/rsvd.h"
#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/core/material.h"
#include "btf/io/package.h"
#include "btf/io/source.h"

namespace btf::factor {

/// Storage of the factors in a package.
enum class Quantization {
    kF32,  ///< IEEE float32
    kF16,  ///< IEEE half (relative error ≤ 2⁻¹¹ of each value)
    kU8,   ///< 8 bits per value with a per-column (per component, per factor) scale and offset
    /// Quantized with steps from one quality and entropy-coded: the texel factor by 8 × 8 DCT
    /// (factor/coded.h)
    kCoded,
};
std::string to_string(Quantization q);
/// "f32", "f16", "u8" or "coded"; throws btf::Error otherwise.
Quantization parse_quantization(const std::string& text);
/// Bytes of one quantized factor column of n values (a component section holds the a and the b
/// column of its component); for kCoded, whose size depends on the values, the f16 size as an
/// estimate.
size_t column_bytes(Quantization q, int64_t n);
/// The default of `quality` (coded storage, factor/coded.h).
constexpr double kDefaultCodingQuality = 50;

/// How RGB values become the planes that are factorized.
enum class ColourBasis {
    kRgb,           ///< one plane whose rows hold the 3 channels (colour inside the ABRDF, FMF)
    kDecorrelated,  ///< 3 planes in an orthonormal luminance/chroma basis
    kPerChannel,    ///< 3 planes R, G, B (UBO2014 DFMF colour model 0)
    kUboModel11,    ///< 3 planes (log Y, U/Y, V/Y) of UBO2014 DFMF colour model 11
    kLab,           ///< 3 planes L*, a*, b* (CIELab, D65 white with Y = 1; btf::rgb_to_lab)
};
std::string to_string(ColourBasis basis);
/// "rgb", "decorrelated", "per-channel", "model11" or "lab"; throws btf::Error otherwise.
ColourBasis parse_colour_basis(const std::string& text);

struct ColourHandling {
    ColourBasis basis = ColourBasis::kRgb;
    /// Factorize log(value + log_eps) (dynamic-range reduction for HDR sources). Not combined
    /// with kUboModel11, whose luminance plane is logarithmic already, nor with kLab.
    bool log = false;
    float log_eps = 1e-3f;
    int planes() const { return basis == ColourBasis::kRgb ? 1 : 3; }
    int channels() const { return basis == ColourBasis::kRgb ? 3 : 1; }
    /// The orthonormal basis of kDecorrelated (row-major 3×3): rows (1,1,1)/√3, (1,−1,0)/√2,
    /// (1,1,−2)/√6, so that a squared error in plane space is the same squared error in (log)
    /// RGB and components can be allocated across planes by singular value alone.
    static const std::array<float, 9>& decorrelation();
    /// rgb → plane values (for kRgb: the 3 channels after the optional log).
    Rgb forward(const Rgb& rgb) const;
    /// plane values → rgb.
    Rgb inverse(const Rgb& planes) const;
};

struct Block {
    int plane = 0, group = 0, cluster = 0;
    int level = 0;    ///< spatial level: b holds (width >> level) × (height >> level) texels
    int angular = 0;  ///< angular level: a holds the (view, light) pairs of that level
    std::vector<float> mean;  ///< one per row, or empty (no centring)
    Matrix a;                 ///< rows × K
    Matrix b;                 ///< texels of the cluster (at the block's level) × K
    /// Energy of each component (singular value, or the norm of a·bᵀ's column product); the
    /// package stores components of all blocks in decreasing energy.
    std::vector<float> energy;
    int components() const { return static_cast<int>(a.cols()); }
};

struct Model {
    int width = 0, height = 0;
    Sampling sampling;
    bool hdr = false;  ///< the source's values may exceed 1 (recorded in the package header)
    ColourHandling colour;
    /// View indices of each group; every view is in exactly one group.
    std::vector<std::vector<int>> groups;
    int clusters = 1;
    /// Cluster of each texel (y · width + x); empty when clusters == 1.
    std::vector<int32_t> texel_cluster;
    /// Spatial levels (1: every b at full resolution); more need clusters == 1 and width and
    /// height divisible by 2^(levels − 1).
    int levels = 1;
    /// Directions of angular levels 1, 2, … (level 0: the whole sampling).
    std::vector<AngularLevel> angular_levels;
    /// planes × groups × clusters × levels × angular levels blocks, index
    /// (((plane · groups + group) · clusters + cluster) · levels + level) · angular_count() +
    /// angular.
    std::vector<Block> blocks;

    int angular_count() const { return 1 + static_cast<int>(angular_levels.size()); }
    int block_index(int plane, int group, int cluster, int level = 0, int angular = 0) const {
        return (((plane * static_cast<int>(groups.size()) + group) * clusters + cluster) * levels +
                level) *
                   angular_count() +
               angular;
    }
    /// Width and height of the texel grid of `level`.
    int level_width(int level) const { return width >> level; }
    int level_height(int level) const { return height >> level; }
    /// Rows of the blocks of group g at angular level 0: views in g × lights × channels.
    int64_t rows(int group) const;
    /// Rows of a (and of the mean) of a block of group g at angular level m.
    int64_t block_rows(int group, int angular) const;
    /// Texels of each cluster, in texel order (the columns of its level-0 blocks).
    std::vector<std::vector<int32_t>> cluster_texels() const;
    /// Rows of b of a block of `cluster` at `level` (`lists` = cluster_texels()).
    int64_t block_texels(const std::vector<std::vector<int32_t>>& lists, int cluster,
                         int level) const;
    /// Throws btf::Error naming `what` when shapes disagree.
    void validate(const std::string& what) const;
};

/// A model with the extent, sampling, HDR flag and colour handling of `source`, one group of all
/// views and one cluster, without blocks. Throws btf::Error naming the source and `codec` when
/// the source is empty.
Model model_for(const BtfSource& source, const ColourHandling& colour, std::string_view codec);
/// The name of a source in messages: its path, or its format for sources without one.
std::string source_name(const BtfSource& source);
/// A direction set in a package header ({"name", "theta": […], "phi": […]}, radians) and back;
/// directions_from_json throws btf::Error for malformed arrays.
nlohmann::json directions_json(const DirectionSet& set);
DirectionSet directions_from_json(const nlohmann::json& j);

/// Package header fields and sections for a model: "tables" (the views' and lights'
/// AngularInterpolator tables, for viewers), "clusters" (texel clusters, when more than one),
/// "means" (all row means), then one section per component ("b<block>.k<k>": a's column then
/// b's column) in decreasing energy over all blocks. `codec` and `params` go into the header.
/// With kCoded, `quality` (0 to 100) sets the step (factor/coded.h); the header's model then
/// holds "coding": {"quality", "step"}.
Package to_package(const Model& model, std::string_view codec, const nlohmann::json& params,
                   Quantization quantization, double quality = kDefaultCodingQuality);
/// The model in a package or a clean prefix of one: blocks keep the components whose sections
/// are present (possibly none: the means alone). Throws btf::Error naming the package's codec and
/// the problem for inconsistent headers or section sizes.
Model from_package(const Package& package);

/// How a FactorMaterial keeps the rows of its factors in memory.
enum class RowStorage {
    /// IEEE half floats when every factor value is one (the factors of an f16 package, of a
    /// UBO2014 file of half floats), which halves the memory a query touches without changing a
    /// value; float32 otherwise.
    kAuto,
    kFloat,  ///< float32 always (the evaluator before half rows; for comparison)
};

/// The evaluator: eval() interpolates like btf::lookup6d (bilinear in space × ≤3 views × ≤3
/// lights), accumulating the angular and the spatial weights on the factors first
/// (a = Σ w_pair a(row), b = Σ w_texel b(texel), value = a · b) with vectorized component loops.
/// eval_sample() and the stochastic filter (one texel row and one (view, light) row per query)
/// are one dot product of length K per channel; the batch calls prefetch the rows of later
/// queries while computing the current one.
class FactorMaterial final : public Material {
  public:
    explicit FactorMaterial(Model model, RowStorage rows = RowStorage::kAuto);
    ~FactorMaterial() override;

    int width() const override { return m_model.width; }
    int height() const override { return m_model.height; }
    const Sampling& sampling() const override { return m_model.sampling; }
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override;
    Rgb eval_sample(int x, int y, int view, int light) const override;
    void eval_sample_batch(std::span<const SampleIndex> indices, std::span<Rgb> out) const override;

    /// eval() for many queries (out.size() == queries.size()); consecutive queries with the same
    /// directions reuse the angular accumulation.
    void eval_batch(std::span<const Query> queries, std::span<Rgb> out) const override;
    /// The stochastic filter for many queries: exactly the values of ShadingPoint(…,
    /// Filter::kStochastic, u).eval(wi) one by one, with the rows of later queries prefetched.
    void eval_stochastic_batch(std::span<const StochasticQuery> queries,
                               std::span<Rgb> out) const override;
    /// The same value as eval() computed in plain scalar code through lookup6d and
    /// eval_sample_reference(): the reference the vectorized path is tested against.
    Rgb eval_reference(const Uv& uv, const Vec3& wi, const Vec3& wo) const;
    /// eval_sample() in plain scalar code, component by component (the reference of the
    /// vectorized lookup). Indices must be in range.
    Rgb eval_sample_reference(int x, int y, int view, int light) const;

    const Model& model() const { return m_model; }
    /// Components in use per block (after a prefix: fewer).
    int total_components() const;
    /// True when the rows are kept in IEEE half floats (RowStorage::kAuto on exact halves).
    bool half_rows() const;

  protected:
    /// Material::select() exactly, through this material's own view interpolator.
    Selection select(const Uv& uv, const Vec3& wo, double u) const override;
    /// Material::eval_selected() exactly (the light drawn by pick() from the barycentric weights
    /// of wi, then the vectorized eval_sample()), without the virtual calls and range checks.
    Rgb eval_selected(const Selection& s, const Uv& uv, const Vec3& wo,
                      const Vec3& wi) const override;

  private:
    struct Impl;
    Model m_model;
    std::unique_ptr<Impl> m_impl;
};

/// Row batches over a source for factorization: one matrix per (plane, group), batch b = the
/// images of view b (all lights), colour converted by `colour`. Columns are all texels.
class SourceRows final : public RowBatches {
  public:
    SourceRows(const BtfSource& source, ColourHandling colour,
               std::vector<std::vector<int>> groups);
    int matrices() const override;
    int64_t rows(int matrix) const override;
    int64_t cols(int) const override { return m_source.num_texels(); }
    int batches() const override { return m_source.num_views(); }
    void read(int batch, std::vector<int64_t>& first, std::vector<Matrix>& out) const override;
    int64_t batch_rows(int batch, int matrix) const override;

    /// Matrix index of (plane, group).
    int matrix(int plane, int group) const { return plane * m_groups + group; }

  private:
    const BtfSource& m_source;
    ColourHandling m_colour;
    int m_groups;
    std::vector<int> m_group_of_view, m_slot_of_view;
    std::vector<int64_t> m_group_rows;
};

/// Components to keep of each plane's SVD when `components` are shared by all planes: the
/// largest singular values over all planes win (the planes are orthonormal or independent, so a
/// squared error in any plane is the same squared error overall). Zero singular values are not
/// kept.
std::vector<int> allocate_components(const std::vector<const Svd*>& planes, int components);
/// The block of the first `keep` components of `svd`: a = U, b = V·S, energy = S, its mean.
Block make_block(const Svd& svd, int plane, int group, int cluster, int keep);

/// Base of the factorization codecs: encode() = factorize() then to_package(); open() checks the
/// codec name and decodes the model into a FactorMaterial. A codec supplies name, description,
/// params and factorize.
class FactorCodec : public Codec {
  public:
    Package encode(const BtfSource& source, const Params& params, Progress& progress) const final;
    std::unique_ptr<Material> open(const Package& package) const final;

    /// What encode_to_size() chose.
    struct SizeChoice {
        int components = 0;   ///< kept, of the factorization's
        int factorized = 0;   ///< components the factorization made
        double quality = -1;  ///< coded storage's quality (−1: another storage)
        uint64_t bytes = 0;   ///< the package file's size
        /// Mean CIEDE2000 of the package against the source on the sample the choice is made on
        /// (1024 images spread over the (view, light) pairs, 128 texels of each).
        double de2000 = 0;
    };
    /// encode() to a package file of at most `bytes` (as write_package writes it with `write`),
    /// at the lowest error found: factorizes once with `params`, then chooses, with
    /// quantize=coded, the quality (for each, the most components that fit: the first ones in
    /// the package's order) by the mean CIEDE2000 of the decoded choice on a fixed sample of the
    /// source. Throws btf::Error when even one component at quality 0 does not fit.
    Package encode_to_size(const BtfSource& source, const Params& params, uint64_t bytes,
                           const PackageWriteOptions& write, Progress& progress,
                           SizeChoice* choice = nullptr) const;

  protected:
    struct Result {
        Model model;
        nlohmann::json params;  ///< every parameter as used, defaults included
        Quantization quantization = Quantization::kF16;
        double quality = kDefaultCodingQuality;  ///< for kCoded
    };
    /// Reads `params` (reporting unknown ones) and factorizes `source`.
    virtual Result factorize(const BtfSource& source, const Params& params,
                             Progress& progress) const = 0;
};

}  // namespace btf::factor
