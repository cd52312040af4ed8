// SPDX-License-Identifier: MIT
#pragma once
/// fmf: full-matrix factorization of the BTF matrix (rows: view × light [× colour], columns:
/// texels) by a streaming randomized SVD; see fmf.cpp for the user documentation.

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"

namespace btf {

/// The registry entry.
const Codec& fmf_codec();

namespace fmf {

struct Options {
    int components = 32;  ///< total components C (over all planes when colour is decorrelated)
    factor::ColourHandling colour;
    bool subtract_mean = false;  ///< factorize the matrix minus its mean ABRDF (row means)
    /// Block Krylov with q = 1 (3 passes): the fastest configuration within 1 % of the
    /// Eckart–Young optimum on every synthetic preset (docs/benchmarks.md, issue 22).
    factor::SvdMethod svd = factor::SvdMethod::kBlockKrylov;
    int oversampling = 10;
    int block = 0;
    int power_iterations = 1;
    uint64_t seed = 1;
    factor::Quantization quantization = factor::Quantization::kF16;
    double coding_quality = factor::kDefaultCodingQuality;  ///< quantize=coded
};

/// Reads the options from codec parameters (the registry's params()); checks ranges.
Options parse_options(const Params& params);

/// Factorizes `source` in streaming passes (memory: the factors plus one view's images).
factor::Model factorize(const BtfSource& source, const Options& options,
                        Progress& progress = Progress::none());

}  // namespace fmf
}  // namespace btf
