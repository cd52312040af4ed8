// SPDX-License-Identifier: MIT
#pragma once
/// Bonn UBO2014 `.btf` files: BTFs stored as truncated SVDs by the measurement lab
/// (FORMATS.md, "Bonn UBO2014 .btf"). btfkit reads the DFMF body (`!DFMF08FC`, one factorization
/// per decorrelated colour channel) and the FMF body (`!FMF12FCE`, colour inside the matrix), each
/// with or without the trailing `R` that announces rotation matrices, and writes DFMF.
///
/// Decisions (docs/formats.md, "Bonn UBO2014"):
/// - Texel index y·W + x, row-major, (0, 0) = first pixel of the first image row, no flip: btflib's
///   texture decoder. Values are not clamped (UBO2014 data is HDR).
/// - Colour models 0 (RGB) and 11 (log Y, U/Y, V/Y, eps 1e-5) are decoded to linear RGB; other
///   models are refused with an "unsupported" error. rgb_scale_factor is kept in the metadata and
///   not applied (btflib does not apply it either).
/// - If the cosine flag is set, each decoded sample is divided by cos θ of its light direction
///   (clamped below at kMinLightCosine).
/// - The whole factorization is read into memory (it is the compressed form: for a 400² texel,
///   151 × 151 material the factors are a few hundred MB at most); every declared size is checked
///   against the file length before anything is allocated.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/core/material.h"
#include "btf/io/open.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf::ubo2014 {

/// Row-major float matrix: one factor (U or S·V) of one channel; row r is contiguous.
using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// DFMF colour models btfkit decodes (btflib's numbering).
constexpr int32_t kColorModelRgb = 0;      ///< plain RGB
constexpr int32_t kColorModelLogYUV = 11;  ///< (log Y, U/Y, V/Y), eps = kUboLogEps
/// eps of the FMF dynamic-range reduction: value = exp(x) − eps.
constexpr float kDynamicRangeEps = 1e-5f;
/// cos θ_light is clamped to at least this before the cosine flag is divided out, so a light at
/// the horizon cannot produce infinities.
constexpr float kMinLightCosine = 1e-3f;

/// Which body follows the common header.
enum class Body {
    kDfmf,  ///< `!DFMF08FC`: one factorization per colour channel
    kFmf,   ///< `!FMF12FCE`: one factorization, rows (view·nL + light)·nC + channel
};

/// The meta block (FORMATS.md item 2). Fields of higher versions are only read or written when
/// `version` includes them.
struct Meta {
    uint32_t version = 4;           ///< 1..4; a file's higher version keeps its number
    std::string measurement_setup;  ///< at most 80 bytes (NUL-padded in the file)
    std::string image_sensor;       ///< at most 80 bytes
    std::string light_source;       ///< at most 80 bytes
    float ppmm = 0;                 ///< pixels per millimetre
    std::array<float, 3> rgb_scale_factor{1, 1, 1};  ///< stored, not applied
    bool cosine_flag = false;  ///< version ≥ 2: values were multiplied by cos θ_light
    std::string xml;           ///< version ≥ 3: the measurement XML
    /// version ≥ 4: one name per channel; empty for older versions (the channels are then RGB).
    std::vector<std::string> channel_names;
    /// Bytes of a version > 4 block that btfkit does not know and skipped (informational).
    uint32_t skipped_bytes = 0;
};

/// One truncated SVD: value(row, col) = Σ_k u(row, k) · sxv(col, k).
struct Factor {
    int scalar_size = 4;  ///< as stored: 2 = IEEE half, 4 = float32, 8 = float64
    Eigen::VectorXf s;    ///< the K singular values (already multiplied into sxv)
    RowMatrix u;          ///< rows × K
    RowMatrix sxv;        ///< cols × K (cols = width·height, texel index y·width + x)
    int components() const { return static_cast<int>(u.cols()); }
};

/// Everything a UBO2014 file holds, in memory. Later codecs convert this directly.
struct Factorization {
    Body body = Body::kDfmf;
    Meta meta;
    Sampling sampling;  ///< views and the one light set, in the file's order
    int width = 0, height = 0;
    bool rotation_block = false;  ///< the signature ends in R (a rotation block follows w, h)
    std::vector<std::array<float, 9>> rotations;  ///< as stored, 9 floats each

    // DFMF body header
    int32_t color_model = kColorModelRgb;
    std::array<float, 3> color_mean{0, 0, 0};
    std::array<float, 9> color_transform{1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major 3×3

    // FMF body header
    int fmf_header_version = 0;
    uint32_t dynamic_range_reduction = 0;  ///< nonzero: values are exp(x) − kDynamicRangeEps
    int height_map_rows = 0, height_map_cols = 0;  ///< the two uint32 before the height map
    std::vector<float> height_map;                 ///< half floats as stored, row-major

    /// DFMF: one factor per colour channel. FMF: exactly one, rows nL·nV·nC.
    std::vector<Factor> factors;

    /// Colour channels: channel_names.size() for meta version ≥ 4, else 3.
    int num_channels() const;
    /// The signature this factorization is written with, e.g. "!DFMF08FC" or "!FMF12FCER".
    std::string signature() const;

    /// Decoded sample: linear RGB at texel (x, y), view and light indices of `sampling`
    /// (colour model undone, dynamic range restored, cosine divided out).
    Rgb sample(int x, int y, int view, int light) const;
    /// Decoded image of one (view, light) pair: width × height × 3 linear RGB.
    void image(int view, int light, Image& out) const;
    /// Checks the shapes (rows, cols, K, S) against sampling, width, height and the body kind;
    /// throws btf::Error naming `what` (a file name or "factorization") and the mismatch.
    void validate(const std::string& what) const;
};

/// True if `path` is a file that starts with a Bonn .btf signature (also the ones btfkit does not
/// decode, so that opening them reports "unsupported" rather than "unknown format").
bool probe(const std::filesystem::path& path);

/// Reads a whole .btf file. Throws btf::Error naming the file, the byte offset and the problem.
std::shared_ptr<const Factorization> read(const std::filesystem::path& path,
                                          Progress& progress = Progress::none());

/// The registry entry: the file as a BtfSource at its sample directions. `options.views` selects
/// a subset of the file's views (indices into its view set, in the given order).
std::unique_ptr<BtfSource> open(const std::filesystem::path& path, const OpenOptions& options);
/// A BtfSource over a factorization in memory; `path` is reported in info() and errors.
std::unique_ptr<BtfSource> make_source(std::shared_ptr<const Factorization> factorization,
                                       const std::filesystem::path& path,
                                       const std::vector<int>& views = {});

/// A factorization as a Material that interpolates decoded linear RGB samples: bilinear in space
/// × barycentric over views and lights (AngularInterpolator + lookup6d), cosine flag divided out
/// per sample. Used for files with the cosine flag only: every other file is opened through the
/// codecs (btf::open_material, codecs/dfmf_export.h: open_ubo2014_material) as the fmf evaluator
/// of its own factors, which interpolates the colour planes, as the file's package does.
std::unique_ptr<Material> make_material(std::shared_ptr<const Factorization> factorization);

/// Writes `factorization` as `!DFMF08FC` (or `!DFMF08FCR` with its rotations when
/// rotation_block is set) exactly per FORMATS.md items 1–5, atomically. Requires a DFMF body,
/// colour model 0 or 11, three channels, scalar sizes 2 or 4 and meta strings of ≤ 80 bytes.
/// Throws btf::Error naming the file and the problem (e.g. a value beyond the half-float range).
void write_dfmf(const std::filesystem::path& path, const Factorization& factorization,
                Progress& progress = Progress::none());

/// Largest matrix (images × texels per channel) the exact in-memory factorization accepts: 2²⁰
/// samples. The SVD costs O(images · texels · min(images, texels)); the worst shape within the
/// limit (square, 1024 × 1024) took about 15 s and 100 MB for the three channels on a 2-core
/// machine, a UBO2003-like 6561 images × 12² texels about 3 s.
constexpr int64_t kMaxFactorizeSamples = int64_t(1) << 20;

struct FactorizeOptions {
    int components = 16;                      ///< K per channel, clamped to min(images, texels)
    int32_t color_model = kColorModelLogYUV;  ///< 0 or 11
    int scalar_size = 4;                      ///< 2 (half) or 4 (float32)
    /// Meta block to write; if meta.cosine_flag is set the source values are multiplied by
    /// cos θ_light before factorizing (a reader divides it out again).
    Meta meta;
    int64_t max_samples = kMaxFactorizeSamples;  ///< refuse larger sources
};

/// Exact truncated SVD (Eigen BDCSVD, double) of each colour channel of a small source, all in
/// memory: rows = view·nL + light, cols = y·W + x. Throws btf::Error if images × texels exceeds
/// options.max_samples. Meant for tests and small sources; large ones need a streaming codec.
Factorization factorize(const BtfSource& source, const FactorizeOptions& options = {},
                        Progress& progress = Progress::none());

/// factorize() then write_dfmf().
void write_dfmf(const std::filesystem::path& path, const BtfSource& source,
                const FactorizeOptions& options = {}, Progress& progress = Progress::none());

}  // namespace btf::ubo2014
