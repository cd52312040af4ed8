// SPDX-License-Identifier: MIT
#pragma once
/// Writing any BTF as a Bonn UBO2014 DFMF file (`!DFMF08FC`) through the fmf codec's streaming
/// factorization, so that sources of any size can be exported (the exact in-memory SVD of
/// ubo2014::factorize is limited to small sources).
///
/// DFMF holds one truncated SVD per colour channel with rows view·nL + light and columns
/// y·W + x. An fmf model with one group of all views, one cluster, no row means and three planes
/// (colour model 0: R, G, B; colour model 11: log Y, U/Y, V/Y) is exactly that: per plane,
/// U = a (rows reordered to view order), S·V = b, S = the components' energies. fmf keeps the
/// same number of components in each of these planes (fewer only where a plane's rank is
/// smaller); DFMF stores a count per channel, so either way is written as it is.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "btf/codecs/factor/model.h"
#include "btf/io/source.h"
#include "btf/io/ubo2014.h"
#include "btf/util/progress.h"

namespace btf {

struct DfmfExportOptions {
    /// Components per colour channel (at most min(views × lights, texels) are kept).
    int components = 16;
    /// ubo2014::kColorModelRgb (0) or ubo2014::kColorModelLogYUV (11).
    int32_t color_model = ubo2014::kColorModelLogYUV;
    int scalar_size = 4;  ///< 2 (half) or 4 (float32) in the file
    ubo2014::Meta meta;   ///< written as given (cosine_flag must be false: fmf sees raw values)
    uint64_t seed = 1;    ///< of the randomized SVD
};

/// The DFMF factorization equal to `model`. Throws btf::Error naming `what` when the model is
/// not DFMF-shaped (more than one view group or texel cluster, row means, log colour, a colour
/// basis other than per-channel or model 11).
ubo2014::Factorization to_dfmf(const factor::Model& model, int scalar_size,
                               const ubo2014::Meta& meta, const std::string& what);

/// The inverse of to_dfmf(), without refactorizing: the fmf model whose value at every sample is
/// the factorization's (its factors as they are: DFMF colour model 0 → per-channel planes, 11 →
/// model11 planes; an FMF body → one rgb plane, with log colour of eps 1e-5 when its dynamic range
/// is reduced). Throws btf::Error naming `what` for a factorization the factor model cannot hold
/// yet: one whose values were multiplied by cos θ_light (the meta block's cosine flag).
factor::Model model_of(const ubo2014::Factorization& factorization, const std::string& what);

/// A UBO2014 factorization as a Material: the fmf evaluator (factor::FactorMaterial) of
/// model_of(`factorization`), the same material as its package (package_of): bilinear in space ×
/// barycentric over views and lights on the colour planes (DFMF model 0: R, G, B; model 11: log Y,
/// U/Y, V/Y; FMF: the rows' channels, logarithmic when its dynamic range is reduced), decoded to
/// linear RGB after the interpolation. Equal to the file's decoded values at its sample directions
/// and texel centres. The factorization is released (if nobody else holds it) before the
/// evaluator's own copy of the factors is made, so that the peak is two copies of the factors, not
/// three. A file with the cosine flag, which the factor model cannot hold, is opened as
/// ubo2014::make_material (decoded RGB samples interpolated). Throws btf::Error naming `what`.
std::unique_ptr<Material> ubo2014_material(
    std::shared_ptr<const ubo2014::Factorization> factorization, const std::string& what);
/// ubo2014::read(`path`) then ubo2014_material(); what btf::open_material does with a .btf file.
std::unique_ptr<Material> open_ubo2014_material(const std::filesystem::path& path,
                                                Progress& progress = Progress::none());

/// The fmf package of model_of(`factorization`): its factors in half floats when the file holds
/// half floats, else float32 (no rounding beyond the file's own); header parameters say where it
/// came from ("from": the file's signature).
Package package_of(const ubo2014::Factorization& factorization, const std::string& what);

/// fmf::factorize (no mean subtraction) then to_dfmf().
ubo2014::Factorization factorize_dfmf(const BtfSource& source, const DfmfExportOptions& options,
                                      Progress& progress = Progress::none());

/// factorize_dfmf() then ubo2014::write_dfmf() (atomic).
void export_dfmf(const std::filesystem::path& path, const BtfSource& source,
                 const DfmfExportOptions& options, Progress& progress = Progress::none());

}  // namespace btf
