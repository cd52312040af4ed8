// SPDX-License-Identifier: MIT
#pragma once
/// lpca: local PCA, texels clustered by their ABRDF with one PCA per cluster (Müller, Meseth and
/// Klein 2003); see lpca.cpp for the user documentation.

#include <cstdint>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"

namespace btf {

/// The registry entry.
const Codec& lpca_codec();

namespace lpca {

struct Options {
    int clusters = 7;    ///< k-means clusters of texels (fewer when the data has fewer distinct)
    int components = 5;  ///< per cluster (over all planes when colour is decorrelated)
    factor::ColourHandling colour;
    int iterations = 20;  ///< Lloyd iterations of k-means at most
    int projection = 32;  ///< rank R of the projection the texels are clustered in
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

/// k-means of the rows of `points` (k-means++ seeding from `seed`, then at most `iterations`
/// Lloyd iterations). An empty cluster is re-seeded with the point farthest from its centre;
/// clusters that stay empty (fewer distinct points than `clusters`) are dropped. Returns each
/// row's cluster, numbered 0.. in the order of their first row. Deterministic for a given seed
/// and independent of the number of threads.
std::vector<int32_t> kmeans(const factor::Matrix& points, int clusters, int iterations,
                            uint64_t seed);

/// The Lloyd iterations of kmeans() from the given initial centres (one per row), with the same
/// handling of empty clusters and the same numbering.
std::vector<int32_t> lloyd(const factor::Matrix& points, const factor::Matrix& initial,
                           int iterations);

/// Each texel's coordinates in the rank-`projection` principal subspace of the centred ABRDFs
/// (rows of v·diag(σ) of a randomized SVD, planes side by side): Euclidean distances between
/// rows approximate distances between the texels' ABRDFs in plane space.
factor::Matrix project_texels(const BtfSource& source, const Options& options,
                              Progress& progress = Progress::none());

/// Row batches of per-cluster matrices over a source: matrix (plane · clusters + cluster) holds
/// the columns of the cluster's texels (in texel order) of the plane's matrix of one group of
/// all views; batch b is view b.
class ClusterRows final : public factor::RowBatches {
  public:
    ClusterRows(const BtfSource& source, factor::ColourHandling colour,
                std::vector<std::vector<int32_t>> cluster_texels);
    int matrices() const override;
    int64_t rows(int matrix) const override;
    int64_t cols(int matrix) const override;
    int batches() const override { return m_rows.batches(); }
    void read(int batch, std::vector<int64_t>& first,
              std::vector<factor::Matrix>& out) const override;
    int64_t batch_rows(int batch, int matrix) const override {
        return m_rows.batch_rows(batch,
                                 m_rows.matrix(matrix / static_cast<int>(m_texels.size()), 0));
    }

  private:
    factor::SourceRows m_rows;
    int m_planes;
    std::vector<std::vector<int32_t>> m_texels;
};

/// Clusters the texels and factorizes each cluster in streaming passes (memory: the factors,
/// the projected texels and one view's images).
factor::Model factorize(const BtfSource& source, const Options& options,
                        Progress& progress = Progress::none());

}  // namespace lpca
}  // namespace btf
