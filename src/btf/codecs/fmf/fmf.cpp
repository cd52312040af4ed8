// fmf — full-matrix factorization (Koudelka et al. 2003; the Bonn FMF of `001`).
//
// The BTF as one matrix: rows are the angular samples (view · nL + light, times the three colour
// channels in `rgb` mode), columns the texels. A truncated SVD keeps C components; a value is
//     mean(row) + Σ_k a(row, k) · b(texel, k)      (a = U, b = S·V)
// The SVD is a randomized one (Halko–Martinsson–Tropp): a Gaussian sketch, q power iterations and
// a small exact SVD, computed in 2 + 2q streaming passes over the source, one view's images at a
// time, so memory stays at the factors plus one view even for a BTF larger than RAM.
//
// Parameters (btf codecs fmf):
//   components=C        components kept (rgb: of the one matrix; decorrelated: in total over the
//                       three planes, allocated by largest singular value as in `003` §5.1;
//                       per-channel and model11: per plane, as UBO2014 DFMF files need)
//   colour=rgb          rgb (colour inside the ABRDF, as FMF), decorrelated (orthonormal
//                       luminance/chroma planes), per-channel (R, G, B planes), model11 (UBO log
//                       Y, U/Y, V/Y planes)
//   mean=false          subtract the mean ABRDF (row means) before factorizing
//   log=false           factorize log(value + log-eps): dynamic-range reduction for HDR sources
//   log-eps=0.001
//   oversampling=10, power-iterations=3, seed=1   randomized SVD settings
//   quantize=f16        factor storage: f32, f16, u8

#include "btf/codecs/fmf/fmf.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>

#include "btf/util/error.h"

namespace btf {

namespace fmf {

namespace {

std::vector<ParamInfo> parameters() {
    std::vector<ParamInfo> p = {
        {"components", "32",
         "components kept (decorrelated: in total over the planes; per-channel, model11: per "
         "plane)"},
        {"colour", "rgb", "rgb, decorrelated, per-channel or model11"},
        {"mean", "false", "subtract the mean ABRDF before factorizing"},
        {"log", "false", "factorize log(value + log-eps) (HDR dynamic-range reduction)"},
        {"log-eps", "0.001", "offset of the log"},
        {"oversampling", "10", "extra random vectors of the randomized SVD"},
        {"power-iterations", "3", "power iterations of the randomized SVD (2 passes each)"},
        {"seed", "1", "random seed"},
    };
    for (ParamInfo& q : factor::quantization_params()) p.push_back(std::move(q));
    return p;
}

}  // namespace

Options parse_options(const Params& params) {
    Options o;
    o.components = params.get_int("components", o.components, 1, 4096);
    o.colour.basis = factor::parse_colour_basis(
        params.get_choice("colour", "rgb", {"rgb", "decorrelated", "per-channel", "model11"}));
    o.subtract_mean = params.get_bool("mean", false);
    o.colour.log = params.get_bool("log", false);
    o.colour.log_eps = static_cast<float>(params.get_double("log-eps", 1e-3, 1e-12, 1e3));
    if (o.colour.log && o.colour.basis == factor::ColourBasis::kUboModel11)
        fail("parameter log: model11 is logarithmic already");
    o.oversampling = params.get_int("oversampling", o.oversampling, 0, 1024);
    o.power_iterations = params.get_int("power-iterations", o.power_iterations, 0, 64);
    o.seed = static_cast<uint64_t>(params.get_int("seed", 1, 0, 1 << 30));
    o.quantization = factor::parse_quantization(params.get_string("quantize", "f16"));
    params.check_all_used("fmf", parameters());
    return o;
}

factor::Model factorize(const BtfSource& source, const Options& options, Progress& progress) {
    factor::Model model = factor::model_for(source, options.colour, "fmf");
    const factor::SourceRows rows(source, options.colour, model.groups);

    factor::SvdOptions svd;
    svd.rank = options.components;
    svd.oversampling = options.oversampling;
    svd.power_iterations = options.power_iterations;
    svd.subtract_mean = options.subtract_mean;
    svd.seed = options.seed;
    std::vector<factor::Svd> planes = factor::randomized_svd(rows, svd, progress);

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
    std::vector<ParamInfo> params() const override { return fmf::parameters(); }

  protected:
    Result factorize(const BtfSource& source, const Params& params,
                     Progress& progress) const override {
        const fmf::Options options = fmf::parse_options(params);
        Result result;
        result.model = fmf::factorize(source, options, progress);
        result.params = {{"components", options.components},
                         {"colour", factor::to_string(options.colour.basis)},
                         {"mean", options.subtract_mean},
                         {"log", options.colour.log},
                         {"log-eps", options.colour.log_eps},
                         {"oversampling", options.oversampling},
                         {"power-iterations", options.power_iterations},
                         {"seed", options.seed},
                         {"quantize", factor::to_string(options.quantization)}};
        result.quantization = options.quantization;
        return result;
    }
};

}  // namespace

const Codec& fmf_codec() {
    static const FmfCodec codec;
    return codec;
}

}  // namespace btf
