// SPDX-License-Identifier: MIT
#pragma once
/// The parameters the factorization codecs share (fmf, pca-views, lpca, perceptual), declared
/// once here for all of them. A codec's Options holds them in members of these names:
///   colour (ColourHandling), quantization, oversampling, power_iterations, seed;
/// each codec's own default (power-iterations=2 for pca-views and lpca, 3 for fmf and perceptual)
/// is its Options initializer, as for every parameter (codecs/param_schema.h).

#include <string>
#include <utility>
#include <vector>

#include "btf/codecs/factor/model.h"
#include "btf/codecs/factor/rsvd.h"
#include "btf/codecs/param_schema.h"

namespace btf::factor {

/// colour=… over `bases` (the default is the Options initializer's), log=… and log-eps=…, and the
/// check that log is not combined with model11.
template <class Options>
void declare_colour(ParamSchema<Options>& schema, const std::vector<ColourBasis>& bases,
                    std::string colour_help) {
    std::vector<std::pair<std::string, ColourBasis>> choices;
    for (ColourBasis b : bases) choices.emplace_back(to_string(b), b);
    schema
        .choice(
            "colour", [](auto& o) -> auto& { return o.colour.basis; }, std::move(choices),
            std::move(colour_help))
        .flag(
            "log", [](auto& o) -> auto& { return o.colour.log; },
            "factorize log(value + log-eps) (dynamic-range reduction for HDR sources)")
        .number(
            "log-eps", [](auto& o) -> auto& { return o.colour.log_eps; }, 1e-12, 1e3,
            "offset of the log");
    schema.then([](Options& o) {
        if (o.colour.log && o.colour.basis == ColourBasis::kUboModel11)
            fail("parameter log: model11 is logarithmic already");
    });
}

/// quantize=… (factor storage) and the randomized SVD's method, oversampling, power-iterations,
/// block, seed.
template <class Options>
void declare_storage_and_svd(ParamSchema<Options>& schema) {
    schema
        .choice("quantize", &Options::quantization,
                std::vector<std::pair<std::string, Quantization>>{{"f32", Quantization::kF32},
                                                                  {"f16", Quantization::kF16},
                                                                  {"u8", Quantization::kU8},
                                                                  {"coded", Quantization::kCoded}},
                "factor storage: f32, f16, u8 (8 bits with per-component scale) or coded "
                "(steps from quality=, texels by 8×8 DCT, entropy-coded)")
        .choice("svd", &Options::svd,
                std::vector<std::pair<std::string, SvdMethod>>{{"subspace", SvdMethod::kSubspace},
                                                               {"krylov", SvdMethod::kBlockKrylov}},
                "randomized SVD: subspace iteration (2 + 2q passes over the source) or block "
                "Krylov (q + 2 passes, about half the products for equal accuracy)")
        .integer("oversampling", &Options::oversampling, 0, 4096,
                 "extra random vectors of the randomized SVD (krylov: its blocks span "
                 "2·(rank + oversampling) columns)")
        .integer("power-iterations", &Options::power_iterations, 0, 64,
                 "q: power iterations of subspace iteration; krylov makes q + 2 blocks")
        .integer("block", &Options::block, 0, 4096,
                 "krylov: columns per block (0: 2·(rank + oversampling)/(q + 2))")
        .integer("seed", &Options::seed, 0, 1 << 30, "random seed of the randomized SVD");
}

/// quality=… of coded storage (Options::coding_quality), after declare_storage_and_svd. A
/// quality other than the default without quantize=coded is refused rather than ignored (it
/// would be a mistake, or perceptual's omission quality under its old name, now base-quality).
/// `hint` ends that error (perceptual: where the old meaning went).
template <class Options>
void declare_coding(ParamSchema<Options>& schema, std::string hint = "") {
    schema.number("quality", &Options::coding_quality, 0, 100,
                  "quantize=coded: 0 to 100, each 10 more halving the quantization step (the "
                  "step is 2^(-quality/10) of the values' RMS)");
    schema.then([hint = std::move(hint)](Options& o) {
        if (o.quantization != Quantization::kCoded && o.coding_quality != kDefaultCodingQuality)
            fail(
                "parameter quality: it sets the quantization step of quantize=coded, and "
                "quantize is {}{}",
                to_string(o.quantization), hint);
    });
}

/// The randomized SVD's settings from a codec's options: rank and centring from the caller.
template <class Options>
SvdOptions svd_options(const Options& options, int rank, bool subtract_mean) {
    SvdOptions out;
    out.rank = rank;
    out.method = options.svd;
    out.oversampling = options.oversampling;
    out.power_iterations = options.power_iterations;
    out.block = options.block;
    out.subtract_mean = subtract_mean;
    out.seed = options.seed;
    return out;
}

}  // namespace btf::factor
