// SPDX-License-Identifier: MIT
// fmf — full-matrix factorization (Koudelka et al. 2003; the Bonn FMF of `001`).
//
// The BTF as one matrix: rows are the angular samples (view · nL + light, times the three colour
// channels in `rgb` mode), columns the texels. A truncated SVD keeps C components; a value is
//     mean(row) + Σ_k a(row, k) · b(texel, k)      (a = U, b = S·V)
// The SVD is a randomized one (factor/rsvd.h): by default block Krylov, q + 2 = 3 streaming passes
// over the source, or Halko–Martinsson–Tropp subspace iteration (svd=subspace, 2 + 2q passes),
// one view's images at a time, so memory stays at the factors plus one view even for a BTF larger
// than RAM.
//
// Parameters: schema() below declares each once (name, range, help; the default is the Options
// initializer in fmf.h); `btf codecs` lists them. How components are counted: rgb keeps C of the
// one matrix; decorrelated keeps C in total over the three planes, allocated by largest singular
// value as in `003` §5.1; per-channel and model11 keep C per plane, as UBO2014 DFMF files need.
// Colour bases: rgb (colour inside the ABRDF, as FMF), decorrelated (orthonormal luminance/chroma
// planes), per-channel (R, G, B planes), model11 (UBO log Y, U/Y, V/Y planes).

#include "btf/codecs/fmf/fmf.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>

#include "btf/codecs/factor/params.h"
#include "btf/util/error.h"

namespace btf {

namespace fmf {

namespace {

const ParamSchema<Options>& schema() {
    static const ParamSchema<Options> schema = [] {
        ParamSchema<Options> s{"fmf"};
        s.integer("components", &Options::components, 1, 4096,
                  "components kept (decorrelated: in total over the planes; per-channel, model11: "
                  "per plane)");
        factor::declare_colour(s,
                               {factor::ColourBasis::kRgb, factor::ColourBasis::kDecorrelated,
                                factor::ColourBasis::kPerChannel, factor::ColourBasis::kUboModel11},
                               "rgb, decorrelated, per-channel or model11");
        s.flag("mean", &Options::subtract_mean, "subtract the mean ABRDF before factorizing");
        factor::declare_storage_and_svd(s);
        factor::declare_coding(s);
        return s;
    }();
    return schema;
}

}  // namespace

Options parse_options(const Params& params) {
    return schema().parse(params);
}

factor::Model factorize(const BtfSource& source, const Options& options, Progress& progress) {
    factor::Model model = factor::model_for(source, options.colour, "fmf");
    const factor::SourceRows rows(source, options.colour, model.groups);

    std::vector<factor::Svd> planes = factor::randomized_svd(
        rows, factor::svd_options(options, options.components, options.subtract_mean), progress);

    // Components per plane: all of them, or for decorrelated planes the C largest singular values
    // over the three planes (003 §5.1).
    std::vector<int> keep(planes.size());
    for (size_t p = 0; p < planes.size(); ++p) keep[p] = static_cast<int>(planes[p].sigma.size());
    if (options.colour.basis == factor::ColourBasis::kDecorrelated) {
        std::vector<const factor::Svd*> pointers;
        for (const factor::Svd& svd : planes) pointers.push_back(&svd);
        keep = factor::allocate_components(pointers, options.components);
    }
    for (size_t p = 0; p < planes.size(); ++p)
        model.blocks.push_back(factor::make_block(planes[p], static_cast<int>(p), 0, 0, keep[p]));
    model.validate("fmf");
    return model;
}

}  // namespace fmf

namespace {

class FmfCodec final : public factor::FactorCodec {
  public:
    std::string_view name() const override { return "fmf"; }
    std::string_view description() const override {
        return "full-matrix factorization: streaming randomized SVD of the whole BTF matrix";
    }
    std::vector<ParamInfo> params() const override { return fmf::schema().infos(); }
    void validate(const Params& params) const override { fmf::schema().parse(params); }

  protected:
    Result factorize(const BtfSource& source, const Params& params,
                     Progress& progress) const override {
        const fmf::Options options = fmf::schema().parse(params);
        Result result;
        result.model = fmf::factorize(source, options, progress);
        result.params = fmf::schema().to_json(options);
        result.quantization = options.quantization;
        result.quality = options.coding_quality;
        return result;
    }
};

}  // namespace

const Codec& fmf_codec() {
    static const FmfCodec codec;
    return codec;
}

}  // namespace btf
