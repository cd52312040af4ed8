// SPDX-License-Identifier: MIT
#pragma once
/// perceptual: factorization of the BTF in CIELab weighted by a contrast sensitivity function
/// (Guthe, Müller, Schneider, Klein 2009, "BTF-CIELab", §5); see perceptual.cpp for the user
/// documentation.

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/codecs/perceptual/csf.h"

namespace btf {

/// The registry entry.
const Codec& perceptual_codec();

namespace perceptual {

struct Options {
    int components = 32;  ///< total over the L*, a*, b* planes, allocated by perceptual energy
    Viewing viewing;      ///< resolution (texels per degree) and angular speed (°/s)
    /// Weight by the CSF filters; false factorizes the unfiltered CIELab planes (the unweighted
    /// baseline of the same colour space and allocation).
    bool csf = true;
    bool subtract_mean = false;  ///< centre each angular sample on its mean over the texels
    /// High-frequency omission (§5.3): base quality bq in [0, 1] (parameter base-quality); 1
    /// keeps every eigen-texture at full resolution, lower values trade perceptual quality for
    /// size per component.
    double quality = 1;
    /// Coarsest eigen-texture level omission may choose: 1/2^max_level of the extent per axis
    /// (only levels that divide width and height are considered).
    int max_level = 3;
    /// Coarsest eigen-ABRDF level omission may choose: level j keeps ⌈n / 2^j⌉ of the views and
    /// of the lights (factor/angular_levels.h; only levels keeping at least 3 of each).
    int max_angular_level = 2;
    factor::SvdMethod svd = factor::SvdMethod::kSubspace;
    int oversampling = 10;
    int block = 0;
    int power_iterations = 3;
    uint64_t seed = 1;
    factor::Quantization quantization = factor::Quantization::kF16;
    double coding_quality = factor::kDefaultCodingQuality;  ///< quantize=coded
};

/// Reads the options from codec parameters (the registry's params()); checks ranges and reports
/// unknown parameters.
Options parse_options(const Params& params);

/// What high-frequency omission chose: one entry per kept component, in decreasing perceptual
/// energy (the order in which the greedy choice visits them).
struct OmissionReport {
    struct Component {
        int plane = 0;
        float sigma = 0;  ///< singular value of the filtered plane
        int level = 0;    ///< chosen spatial level of its eigen-texture
        int angular = 0;  ///< chosen angular level of its eigen-ABRDF
        /// The perceptual energy the levels give up (0 at full resolution; see choose_levels)
        double lost = 0;
    };
    std::vector<Component> components;
    /// E: the filtered planes' energy in the sketched subspace, the signal of the quality q.
    double energy = 0;
};

/// Factorizes `source` in streaming passes: 2 + 2 · power_iterations passes of the randomized SVD
/// of the filtered planes, then one pass that accumulates the untransformed factors; then, for
/// quality < 1, chooses each component's spatial and angular level. Fills `report` when given.
factor::Model factorize(const BtfSource& source, const Options& options,
                        Progress& progress = Progress::none(), OmissionReport* report = nullptr);

}  // namespace perceptual
}  // namespace btf
