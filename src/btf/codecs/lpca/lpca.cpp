// SPDX-License-Identifier: MIT
/// # lpca: local PCA
///
/// The texels are clustered by their ABRDFs (apparent BRDFs: every view × light × colour value
/// of one texel), and each cluster gets its own PCA: a mean ABRDF and C principal components,
///
///     value(row, texel) ≈ mean_c[row] + Σ_k u_c(row, k) · σ_k · v_c(texel, k),  c = cluster(texel)
///
/// so materials that differ in kind (fibres and gaps of a fabric, metal and paint) do not compete
/// for the same components. This is the local PCA of Müller, Meseth and Klein, "Compression and
/// Real-Time Rendering of Measured BTFs Using Local PCA" (VMV 2003); Havran, Filip and
/// Myszkowski, "Bidirectional Texture Function Compression Based on Multi-Level Vector
/// Quantization" (CGF 2010), §7, use it with 7 clusters × 5 components (the defaults here) as
/// their baseline, at a compression ratio of about 1:275 on Bonn UBO2003 data.
///
/// A BTF may be larger than memory, so the clustering works on a projection: a streaming
/// randomized SVD of the centred BTF matrix (one group of all views, rank `projection`) gives
/// every texel R coordinates, the rows of v·diag(σ), whose Euclidean distances approximate
/// those between the texels' centred ABRDFs. k-means (k-means++ seeding, Lloyd iterations) on
/// these coordinates clusters the texels. Then a second streaming randomized SVD factorizes the
/// clusters' matrices (rows centred per cluster) in the same passes. The source is read
/// 2·(2 + 2·power-iterations) times, a view at a time. Müller et al. instead alternate between
/// assigning texels to the cluster whose local PCA reconstructs them best and refitting, which
/// needs the whole BTF in memory; k-means in the principal subspace is its one-pass counterpart.
/// Clusters that end up empty (data with fewer distinct ABRDFs than `clusters`) are dropped.
///
/// Parameters: schema() below declares each once (the default is the Options initializer in
/// lpca.h); `btf codecs` lists them. With decorrelated colour, a cluster's components are shared
/// by its three planes, allocated by singular value.
///
/// Package: the shared factor model (factor/model.h) with the texel clusters as a section, the
/// row means of every cluster, then the components of all clusters in decreasing energy, so a
/// prefix of the package is a material with fewer components.

#include "btf/codecs/lpca/lpca.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <tuple>

#include "btf/codecs/factor/params.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {
namespace lpca {

namespace {

constexpr std::string_view kName = "lpca";

using Centres = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

const ParamSchema<Options>& schema() {
    static const ParamSchema<Options> schema = [] {
        ParamSchema<Options> s{std::string(kName)};
        s.integer("clusters", &Options::clusters, 1, 1 << 16,
                  "texel clusters (k-means of the texels' ABRDFs)")
            .integer("components", &Options::components, 1, 1 << 16,
                     "principal components per cluster (shared by the planes when decorrelated)");
        factor::declare_colour(s, {factor::ColourBasis::kRgb, factor::ColourBasis::kDecorrelated},
                               "rgb (colour inside the rows) or decorrelated (luminance/chroma)");
        s.integer("iterations", &Options::iterations, 0, 10000,
                  "Lloyd iterations of k-means at most")
            .integer("projection", &Options::projection, 1, 4096,
                     "rank of the subspace the texels are clustered in");
        factor::declare_storage_and_svd(s);
        factor::declare_coding(s);
        return s;
    }();
    return schema;
}

std::vector<int> all_views(const BtfSource& source) {
    std::vector<int> views(source.num_views());
    std::iota(views.begin(), views.end(), 0);
    return views;
}

double squared_distance(const factor::Matrix& points, int64_t i, const Centres& centres, int c) {
    return (points.row(i).cast<double>() - centres.row(c)).squaredNorm();
}

// Nearest live centre of every point (ties: the lower index) and its squared distance.
void assign(const factor::Matrix& points, const Centres& centres, const std::vector<char>& live,
            std::vector<int32_t>& label, std::vector<double>& distance) {
    parallel_for(0, points.rows(), [&](int64_t i) {
        int best = -1;
        double best_distance = 0;
        for (int c = 0; c < centres.rows(); ++c) {
            if (!live[c]) continue;
            const double d = squared_distance(points, i, centres, c);
            if (best < 0 || d < best_distance) best = c, best_distance = d;
        }
        label[i] = best;
        distance[i] = best_distance;
    });
}

class LpcaCodec final : public factor::FactorCodec {
  public:
    std::string_view name() const override { return kName; }
    std::string_view description() const override {
        return "local PCA: k-means clusters of texel ABRDFs, one PCA per cluster";
    }
    std::vector<ParamInfo> params() const override { return schema().infos(); }
    void validate(const Params& params) const override { schema().parse(params); }

  protected:
    Result factorize(const BtfSource& source, const Params& params,
                     Progress& progress) const override {
        const Options options = schema().parse(params);
        return {lpca::factorize(source, options, progress), schema().to_json(options),
                options.quantization, options.coding_quality};
    }
};

}  // namespace

Options parse_options(const Params& params) {
    return schema().parse(params);
}

std::vector<int32_t> kmeans(const factor::Matrix& points, int clusters, int iterations,
                            uint64_t seed) {
    const int64_t n = points.rows();
    check(n > 0, "{}: k-means of no points", kName);
    check(clusters >= 1, "{}: k-means with {} clusters", kName, clusters);
    // std::mt19937_64's output is fixed by the standard; the distributions are not, so uniform
    // numbers are made here to keep the clustering identical across standard libraries.
    std::mt19937_64 rng(seed);
    auto uniform = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };

    // k-means++ seeding (Arthur and Vassilvitskii 2007): each further centre is a point drawn
    // with probability proportional to its squared distance to the nearest centre so far.
    Centres centres(clusters, points.cols());
    std::vector<double> nearest(n);
    const int64_t first = std::min<int64_t>(n - 1, static_cast<int64_t>(uniform() * n));
    centres.row(0) = points.row(first).cast<double>();
    parallel_for(0, n, [&](int64_t i) { nearest[i] = squared_distance(points, i, centres, 0); });
    int count = 1;
    while (count < clusters) {
        const double total = std::accumulate(nearest.begin(), nearest.end(), 0.0);
        if (!(total > 0)) break;  // every point coincides with a centre
        const double target = uniform() * total;
        int64_t pick = -1;
        double sum = 0;
        for (int64_t i = 0; i < n; ++i) {
            if (nearest[i] <= 0) continue;
            pick = i;
            sum += nearest[i];
            if (sum > target) break;
        }
        centres.row(count) = points.row(pick).cast<double>();
        parallel_for(0, n, [&](int64_t i) {
            nearest[i] = std::min(nearest[i], squared_distance(points, i, centres, count));
        });
        ++count;
    }
    centres.conservativeResize(count, Eigen::NoChange);
    return lloyd(points, centres.cast<float>(), iterations);
}

std::vector<int32_t> lloyd(const factor::Matrix& points, const factor::Matrix& initial,
                           int iterations) {
    const int64_t n = points.rows();
    const int count = static_cast<int>(initial.rows());
    check(n > 0 && count > 0, "{}: k-means of {} points with {} centres", kName, n, count);
    check(initial.cols() == points.cols(), "{}: k-means centres have {} dimensions, points {}",
          kName, initial.cols(), points.cols());
    Centres centres = initial.cast<double>();
    std::vector<char> live(count, 1);
    std::vector<int32_t> label(n), next(n);
    std::vector<double> distance(n);
    assign(points, centres, live, label, distance);
    for (int iteration = 0; iteration < iterations; ++iteration) {
        // Means in a fixed order (the result does not depend on the number of threads).
        Centres sum = Centres::Zero(count, points.cols());
        std::vector<int64_t> members(count, 0);
        for (int64_t i = 0; i < n; ++i) {
            sum.row(label[i]) += points.row(i).cast<double>();
            ++members[label[i]];
        }
        for (int c = 0; c < count; ++c) {
            if (!live[c]) continue;
            if (members[c] > 0) {
                centres.row(c) = sum.row(c) / static_cast<double>(members[c]);
                continue;
            }
            // An empty cluster takes the point farthest from its centre; none left that is
            // apart from its centre: the cluster is dropped.
            const auto far = std::max_element(distance.begin(), distance.end());
            if (!(*far > 0)) {
                live[c] = 0;
                continue;
            }
            centres.row(c) = points.row(far - distance.begin()).cast<double>();
            *far = 0;
        }
        assign(points, centres, live, next, distance);
        const bool changed = next != label;
        label.swap(next);
        if (!changed) break;
    }

    // Number the non-empty clusters by their first point.
    std::vector<int32_t> number(count, -1);
    int32_t used = 0;
    for (int32_t& l : label) {
        if (number[l] < 0) number[l] = used++;
        l = number[l];
    }
    return label;
}

factor::Matrix project_texels(const BtfSource& source, const Options& options, Progress& progress) {
    const factor::SourceRows rows(source, options.colour, {all_views(source)});
    const std::vector<factor::Svd> svds = factor::randomized_svd(
        rows, factor::svd_options(options, options.projection, true), progress);
    int64_t dims = 0;
    for (const factor::Svd& svd : svds) dims += svd.sigma.size();
    factor::Matrix coordinates(source.num_texels(), dims);
    int64_t column = 0;
    for (const factor::Svd& svd : svds) {
        coordinates.middleCols(column, svd.sigma.size()) = svd.v * svd.sigma.asDiagonal();
        column += svd.sigma.size();
    }
    return coordinates;
}

ClusterRows::ClusterRows(const BtfSource& source, factor::ColourHandling colour,
                         std::vector<std::vector<int32_t>> cluster_texels)
    : m_rows(source, colour, {all_views(source)}),
      m_planes(colour.planes()),
      m_texels(std::move(cluster_texels)) {
    for (const std::vector<int32_t>& texels : m_texels)
        for (int32_t t : texels)
            check(t >= 0 && t < source.num_texels(), "{}: {}: texel {} outside the {}x{} texels",
                  factor::source_name(source), kName, t, source.width(), source.height());
}

int ClusterRows::matrices() const {
    return m_planes * static_cast<int>(m_texels.size());
}

int64_t ClusterRows::rows(int matrix) const {
    return m_rows.rows(m_rows.matrix(matrix / static_cast<int>(m_texels.size()), 0));
}

int64_t ClusterRows::cols(int matrix) const {
    return static_cast<int64_t>(m_texels[matrix % m_texels.size()].size());
}

void ClusterRows::read(int batch, std::vector<int64_t>& first,
                       std::vector<factor::Matrix>& out) const {
    std::vector<int64_t> plane_first;
    std::vector<factor::Matrix> plane_rows;
    m_rows.read(batch, plane_first, plane_rows);
    const int clusters = static_cast<int>(m_texels.size());
    first.assign(matrices(), 0);
    out.resize(matrices());
    for (int p = 0; p < m_planes; ++p) {
        const int source_matrix = m_rows.matrix(p, 0);
        const factor::Matrix& in = plane_rows[source_matrix];
        for (int c = 0; c < clusters; ++c) {
            const std::vector<int32_t>& texels = m_texels[c];
            factor::Matrix& o = out[p * clusters + c];
            first[p * clusters + c] = plane_first[source_matrix];
            o.resize(in.rows(), static_cast<int64_t>(texels.size()));
            parallel_for(0, in.rows(), [&](int64_t r) {
                const float* from = in.row(r).data();
                float* to = o.row(r).data();
                for (size_t j = 0; j < texels.size(); ++j) to[j] = from[texels[j]];
            });
        }
    }
}

factor::Model factorize(const BtfSource& source, const Options& options, Progress& progress) {
    factor::Model model = factor::model_for(source, options.colour, kName);

    std::vector<int32_t> label;
    {
        const factor::Matrix coordinates = project_texels(source, options, progress);
        progress.begin("clustering texels", 1);
        label = kmeans(coordinates, options.clusters, options.iterations, options.seed);
        progress.advance();
        progress.finish();
    }
    const int clusters = 1 + *std::max_element(label.begin(), label.end());
    std::vector<std::vector<int32_t>> texels(clusters);
    for (size_t t = 0; t < label.size(); ++t) texels[label[t]].push_back(static_cast<int32_t>(t));
    model.clusters = clusters;
    if (clusters > 1) model.texel_cluster = label;

    const ClusterRows rows(source, options.colour, texels);
    const std::vector<factor::Svd> svds = factor::randomized_svd(
        rows, factor::svd_options(options, options.components, true), progress);
    const int planes = options.colour.planes();
    model.blocks.resize(static_cast<size_t>(planes) * clusters);
    for (int c = 0; c < clusters; ++c) {
        std::vector<const factor::Svd*> cluster_svds;
        for (int p = 0; p < planes; ++p) cluster_svds.push_back(&svds[p * clusters + c]);
        const std::vector<int> keep = factor::allocate_components(cluster_svds, options.components);
        for (int p = 0; p < planes; ++p)
            model.blocks[model.block_index(p, 0, c)] =
                factor::make_block(*cluster_svds[p], p, 0, c, keep[p]);
    }
    model.validate(std::string(kName));
    return model;
}

}  // namespace lpca

const Codec& lpca_codec() {
    static const lpca::LpcaCodec codec;
    return codec;
}

}  // namespace btf
