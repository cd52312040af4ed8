// SPDX-License-Identifier: MIT
/// # pca-views: PCA over groups of neighbouring views
///
/// The views of the BTF are partitioned into groups of k neighbouring view directions; each
/// group's data is one matrix (rows: the group's views × lights [× colour channels], columns:
/// texels), centred on its mean row value (the group's mean ABRDF over all texels) and reduced
/// to C principal components by a truncated SVD:
///
///     value(row, texel) ≈ mean[row] + Σ_k u(row, k) · σ_k · v(texel, k)
///
/// k = 1 is PCA-RF (Sattler et al. 2003: one PCA per view, "reflectance fields"); k ≥ the
/// number of views is one group, PCA-BTF (one PCA of the whole BTF). Between the two, k trades
/// compression against the rows one component must explain: Sotnychenko, "Rendering and
/// Streaming of Bidirectional Texture Functions" (Saarland University, 2015), §4.3 and §6.1,
/// reports k = 3, C = 8 as the best trade-off on the Bonn wool sample (same error as k = 1 at a
/// third of the size). The thesis centres each texel's ABRDF on its own mean; here the rows are
/// centred across texels (the usual PCA with texels as observations), which the shared factor
/// model stores as one mean per row.
///
/// Grouping: ⌈n / k⌉ groups whose sizes differ by at most one. Each group is grown from the
/// remaining view farthest from the remaining views' mean direction by adding the remaining view
/// nearest to the group's mean direction; afterwards views are swapped between groups while a
/// swap lowers the summed squared distance of the views to their group centroid. Deterministic.
///
/// All groups are factorized in the same streaming passes of a randomized SVD (Halko et al.
/// 2011): the source is read 2 + 2·power-iterations times, a view at a time, and memory holds
/// only the factors and one view's images.
///
/// Parameters: schema() below declares each once (the default is the Options initializer in
/// pca_views.h); `btf codecs` lists them. With decorrelated colour, a group's C components are
/// shared by its three planes, allocated by singular value (the planes' basis is orthonormal).
///
/// Package: the shared factor model (factor/model.h): view groups in the header, the row means,
/// then the components of all groups in decreasing energy, so a prefix of the package is a
/// material with fewer components.

#include "btf/codecs/pca_views/pca_views.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include "btf/codecs/factor/params.h"
#include "btf/util/error.h"

namespace btf {
namespace pca_views {

namespace {

constexpr std::string_view kName = "pca-views";
// Improving swaps of the grouping stop after this many sweeps (each sweep is O(n²) pairs; the
// swaps converge in a handful of sweeps on real samplings).
constexpr int kMaxSwapSweeps = 100;

const ParamSchema<Options>& schema() {
    static const ParamSchema<Options> schema = [] {
        ParamSchema<Options> s{std::string(kName)};
        s.integer("views-per-group", &Options::views_per_group, 1, 1 << 20,
                  "k: neighbouring views factorized together (1: PCA-RF; >= number of views: one "
                  "group, PCA-BTF)")
            .integer("components", &Options::components, 1, 1 << 16,
                     "principal components per view group (shared by the planes when "
                     "decorrelated)");
        factor::declare_colour(s, {factor::ColourBasis::kRgb, factor::ColourBasis::kDecorrelated},
                               "rgb (colour inside the rows) or decorrelated (luminance/chroma)");
        factor::declare_storage_and_svd(s);
        factor::declare_coding(s);
        return s;
    }();
    return schema;
}

Vec3 unit(const Vec3& v) {
    const double n = length(v);
    return n > 0 ? v / n : v;
}

class PcaViewsCodec final : public factor::FactorCodec {
  public:
    std::string_view name() const override { return kName; }
    std::string_view description() const override {
        return "PCA over groups of k neighbouring views (k=1: PCA-RF, k=all: PCA-BTF)";
    }
    std::vector<ParamInfo> params() const override { return schema().infos(); }
    void validate(const Params& params) const override { schema().parse(params); }

  protected:
    Result factorize(const BtfSource& source, const Params& params,
                     Progress& progress) const override {
        const Options options = schema().parse(params);
        return {pca_views::factorize(source, options, progress), schema().to_json(options),
                options.quantization, options.coding_quality};
    }
};

}  // namespace

Options parse_options(const Params& params) {
    return schema().parse(params);
}

std::vector<std::vector<int>> group_views(const DirectionSet& views, int views_per_group) {
    const int n = views.size();
    check(n > 0, "{}: no views to group", kName);
    check(views_per_group >= 1, "{}: views-per-group {} must be at least 1", kName,
          views_per_group);
    if (views_per_group >= n) {
        std::vector<int> all(n);
        std::iota(all.begin(), all.end(), 0);
        return {all};
    }
    std::vector<Vec3> v(n);
    for (int i = 0; i < n; ++i) v[i] = unit(views.vector(i));

    const int count = (n + views_per_group - 1) / views_per_group;
    std::vector<int> size(count, n / count);
    for (int g = 0; g < n % count; ++g) ++size[g];

    // Greedy growth. Comparisons use a small tolerance so that directions at the same distance
    // (rings of a regular sampling) are taken in index order, not by rounding noise.
    constexpr double kTie = 1e-9;
    std::vector<int> group_of(n, -1);
    std::vector<std::vector<int>> groups(count);
    std::vector<Vec3> sum(count);
    Vec3 remaining;
    for (const Vec3& d : v) remaining += d;
    for (int g = 0; g < count; ++g) {
        int seed = -1;
        double best = 0;
        for (int i = 0; i < n; ++i) {
            if (group_of[i] >= 0) continue;
            const double d = dot(v[i], remaining);
            if (seed < 0 || d < best - kTie) seed = i, best = d;
        }
        auto take = [&](int i) {
            group_of[i] = g;
            groups[g].push_back(i);
            sum[g] += v[i];
            remaining = remaining - v[i];
        };
        take(seed);
        while (static_cast<int>(groups[g].size()) < size[g]) {
            int next = -1;
            double nearest = 0;
            for (int i = 0; i < n; ++i) {
                if (group_of[i] >= 0) continue;
                const double d = dot(v[i], sum[g]);
                if (next < 0 || d > nearest + kTie) next = i, nearest = d;
            }
            take(next);
        }
    }

    // Swaps: the cost of group g is Σ |v - centroid|² = size - |sum|² / size.
    for (int sweep = 0; sweep < kMaxSwapSweeps; ++sweep) {
        bool improved = false;
        for (int i = 0; i < n; ++i) {
            for (int j = i + 1; j < n; ++j) {
                const int g = group_of[i], h = group_of[j];
                if (g == h) continue;
                const Vec3 d = v[j] - v[i];
                const Vec3 sg = sum[g] + d, sh = sum[h] - d;
                const double delta = -(dot(sg, sg) - dot(sum[g], sum[g])) / size[g] -
                                     (dot(sh, sh) - dot(sum[h], sum[h])) / size[h];
                if (delta >= -1e-12) continue;
                sum[g] = sg, sum[h] = sh;
                std::replace(groups[g].begin(), groups[g].end(), i, j);
                std::replace(groups[h].begin(), groups[h].end(), j, i);
                group_of[i] = h, group_of[j] = g;
                improved = true;
            }
        }
        if (!improved) break;
    }
    for (std::vector<int>& group : groups) std::sort(group.begin(), group.end());
    std::sort(groups.begin(), groups.end());
    return groups;
}

factor::Model factorize(const BtfSource& source, const Options& options, Progress& progress) {
    factor::Model model = factor::model_for(source, options.colour, kName);
    model.groups = group_views(source.sampling().views, options.views_per_group);

    const factor::SourceRows rows(source, options.colour, model.groups);
    const std::vector<factor::Svd> svds = factor::randomized_svd(
        rows, factor::svd_options(options, options.components, true), progress);

    const int planes = options.colour.planes();
    const int groups = static_cast<int>(model.groups.size());
    model.blocks.resize(static_cast<size_t>(planes) * groups);
    for (int g = 0; g < groups; ++g) {
        std::vector<const factor::Svd*> group_svds;
        for (int p = 0; p < planes; ++p) group_svds.push_back(&svds[rows.matrix(p, g)]);
        const std::vector<int> keep = factor::allocate_components(group_svds, options.components);
        for (int p = 0; p < planes; ++p)
            model.blocks[model.block_index(p, g, 0)] =
                factor::make_block(*group_svds[p], p, g, 0, keep[p]);
    }
    model.validate(std::string(kName));
    return model;
}

}  // namespace pca_views

const Codec& pca_views_codec() {
    static const pca_views::PcaViewsCodec codec;
    return codec;
}

}  // namespace btf
