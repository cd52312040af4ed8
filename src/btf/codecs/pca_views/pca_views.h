// SPDX-License-Identifier: MIT
#pragma once
/// pca-views: PCA with mean centring over groups of k neighbouring views (k = 1: PCA-RF, k = all
/// views: PCA-BTF); see pca_views.cpp for the user documentation.

#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"

namespace btf {

/// The registry entry.
const Codec& pca_views_codec();

namespace pca_views {

struct Options {
    int views_per_group = 1;  ///< k; k ≥ number of views gives one group (PCA-BTF)
    int components = 8;       ///< C per view group (over all planes when colour is decorrelated)
    factor::ColourHandling colour;
    factor::SvdMethod svd = factor::SvdMethod::kSubspace;
    int oversampling = 10;
    int block = 0;
    int power_iterations = 2;
    uint64_t seed = 1;
    factor::Quantization quantization = factor::Quantization::kF16;
    double coding_quality = factor::kDefaultCodingQuality;  ///< quantize=coded
};

/// Reads the options from codec parameters (the registry's params()); checks ranges and reports
/// unknown parameters.
Options parse_options(const Params& params);

/// Partitions the view directions into groups of neighbouring views: ⌈n / k⌉ groups whose sizes
/// differ by at most one (none larger than k), grown greedily from the outermost remaining view
/// and then improved by swapping views between groups while that lowers the summed squared
/// distance of the views to their group's centroid. Deterministic; every view is in exactly one
/// group; views ascending inside a group, groups ordered by their first view.
std::vector<std::vector<int>> group_views(const DirectionSet& views, int views_per_group);

/// Factorizes `source` in streaming passes (all groups in the same passes; memory: the factors
/// plus one view's images).
factor::Model factorize(const BtfSource& source, const Options& options,
                        Progress& progress = Progress::none());

}  // namespace pca_views
}  // namespace btf
