// SPDX-License-Identifier: MIT
// perceptual — perceptually guided factorization (Guthe, Müller, Schneider, Klein 2009,
// "BTF-CIELab", §5).
//
// The BTF in CIELab as three matrices, one per plane L*, a*, b* (rows: view · nL + light,
// columns: texels). Plain factorization minimizes the squared error of every sample alike; here
// each plane is first weighted by the contrast sensitivity of the eye, a spatial filter T_u on
// every image and an angular filter T_v over the (view, light) pairs (csf.h; Table 2 of the paper,
// the achromatic CSF for L*, the chromatic one for a* and b*), and the filtered matrices
//     Ã = T_v · A · T_uᵀ
// are factorized: the Frobenius norm of Ã − Ã_k is the linearized perceptual error, so the
// truncation keeps what the eye sees and drops what it does not (fine chroma detail first).
//
// Untransformed recovery (§5.4): the filters are never inverted. With Ã ≈ P Σ Qᵀ (P: ABRDFs,
// Q: textures of the filtered planes), one more streaming pass accumulates
//     a = A T_uᵀ Q Σ⁻¹        b = Aᵀ T_vᵀ P
// so that value = a · bᵀ with T_v a bᵀ T_uᵀ = P Σ Qᵀ exactly for an exact SVD
// (factor::untransformed_factors). The factors are neither orthogonal nor normalized; σ of the
// filtered planes is kept as each component's energy, so a package prefix adds components in
// decreasing perceptual energy.
//
// Components: `components` in total, each going to the plane with the largest next filtered
// singular value (§5.1), i.e. the allocation that minimizes the total perceptual error.
//
// Mean: with mean=true each row's mean over the texels (the mean ABRDF) is subtracted before
// filtering and stored unfiltered; the spatial filter keeps constants (DC gain 1, periodic), so
// filtering the centred matrix equals centring the filtered one.
//
// High-frequency omission (§5.3): for quality (bq) < 1 each component's eigen-texture may be
// stored at 1/2, 1/4, … of the extent per axis (a spatial level of the shared model, up-sampled
// bilinearly by the evaluator), and its eigen-ABRDF on ⌈n/2⌉, ⌈n/4⌉, … of the views and of the
// lights (an angular level: nested farthest-point subsets of the measured directions, up-sampled
// barycentrically through their own triangulation; factor/angular_levels.h). The paper resamples
// the ABRDFs onto its square parametrization for this; subsets of the measured directions need no
// second parametrization and keep the interpolation every factor model uses. Reduced factors are
// the least-squares down-sampling of the untransformed full-resolution ones, chosen per
// component in decreasing σ by the paper's score
//     s = bq / (1 − bq) · log(q_new − q_old) − log(bytes),   q = E / e² − 1,
// E the filtered energy (in the sketched subspace) and e² the filtered error left (see
// choose_levels). Components of one plane, spatial and angular level form one block.
//
// Decoding: planes interpolate like every factor model (bilinear in space, barycentric over
// views and lights) and convert to linear RGB by btf::lab_to_rgb after interpolation.
//
// Parameters: schema() below declares each once (the default is the Options initializer in
// perceptual.h); `btf codecs` lists them.

#include "btf/codecs/perceptual/perceptual.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "btf/codecs/factor/params.h"
#include "btf/codecs/perceptual/resample.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {

namespace perceptual {

namespace {

constexpr const char* kName = "perceptual";

// No filtering (csf=false).
class Identity final : public factor::Transforms {
  public:
    void left(int, factor::Matrix&, bool) const override {}
    void right(int, factor::Matrix&, bool) const override {}
};

const ParamSchema<Options>& schema() {
    static const ParamSchema<Options> schema = [] {
        ParamSchema<Options> s{std::string(kName)};
        s.integer("components", &Options::components, 1, 4096,
                  "components kept in total over the L*, a*, b* planes (allocated by perceptual "
                  "energy)")
            .number(
                "resolution", [](auto& o) -> auto& { return o.viewing.resolution; }, 1, 1000,
                "viewing: texels per degree of visual angle (paper's range 2-100)")
            .number(
                "speed", [](auto& o) -> auto& { return o.viewing.speed; }, 1, 10000,
                "viewing: angular speed in degrees per second (paper's range 10-1000)")
            .flag("mean", &Options::subtract_mean,
                  "subtract the mean ABRDF before filtering (stored unfiltered)")
            .flag("csf", &Options::csf,
                  "weight by the CSF filters; false: plain factorization of the CIELab planes "
                  "(baseline)")
            .number("base-quality", &Options::quality, 0, 1,
                    "base quality bq of high-frequency omission: 1 keeps every eigen-texture at "
                    "full resolution, lower values store more of them at reduced resolution")
            .integer("max-level", &Options::max_level, 0, 8,
                     "coarsest eigen-texture resolution omission may choose: 1/2^level per axis")
            .integer("max-angular-level", &Options::max_angular_level, 0, 8,
                     "coarsest eigen-ABRDF resolution omission may choose: 1/2^level of the views "
                     "and of the lights");
        factor::declare_storage_and_svd(s);
        factor::declare_coding(s,
                               "; the base quality bq of high-frequency omission is "
                               "parameter base-quality");
        return s;
    }();
    return schema;
}

}  // namespace

Options parse_options(const Params& params) {
    return schema().parse(params);
}

namespace {

// Levels 1..n that divide the extent, n ≤ max_level.
int usable_levels(int width, int height, int max_level) {
    int n = 0;
    while (n < max_level && width % (2 << n) == 0 && height % (2 << n) == 0) ++n;
    return n;
}

// A kept component: its plane, its index in the plane's factors, its filtered singular value.
struct Item {
    int plane = 0, k = 0;
    float sigma = 0;
};

// A component's resolutions: spatial level of its eigen-texture, angular level of its
// eigen-ABRDF, and the perceptual energy they give up.
struct Choice {
    int level = 0, angular = 0;
    double lost = 0;
};

// High-frequency omission (§5.3): the spatial and angular level of every component. A reduced
// texture is the least-squares down-sampling D b of the untransformed texture b (what
// accumulating down-sampled untransformed basis textures gives, §5.4), a reduced ABRDF likewise
// D a over the nested direction subsets (factor/angular_levels.h). With δb = b − B D b and
// δa = a − U D a the component's error a bᵀ − (a − δa)(b − δb)ᵀ = δa (b − δb)ᵀ + a δbᵀ, filtered:
//     E = x₁ y′ᵀ + x₂ y₂ᵀ,   x₁ = T_v δa, x₂ = T_v a, y′ = T_u (b − δb), y₂ = T_u δb,
//     lost = ‖E‖² = ‖x₁‖²‖y′‖² + ‖x₂‖²‖y₂‖² + 2 (x₁·x₂)(y′·y₂).
// The losses of different components add exactly when they reduce one kind of resolution (the
// x₂ = T_v a are the orthonormal filtered ABRDFs, the y₁ = T_u b = σ q orthogonal filtered
// textures); with both kinds, the sum neglects cross terms between components (a test measures
// them). In decreasing σ the greedy choice maximizes
//     s(r_u, r_v) = bq / (1 − bq) · log(q(ρ_i^{r_u, r_v}) − q_{i−1}) − log m(r_u, r_v),
// q = E / e² − 1 the signal-to-noise energy ratio of the filtered BTF (E its energy, e² the
// remaining error), m the bytes of the component at those resolutions.
std::vector<Choice> choose_levels(const std::vector<Item>& items,
                                  const std::vector<factor::Factors>& factors,
                                  const CsfTransforms* transforms, const factor::Model& model,
                                  const std::vector<factor::AngularLevel>& angular_levels,
                                  const Options& options, double energy) {
    const int levels = usable_levels(model.width, model.height, options.max_level);
    const int angular = static_cast<int>(angular_levels.size());
    std::vector<Choice> chosen(items.size());
    if (options.quality >= 1 || (levels == 0 && angular == 0) || items.empty() || !(energy > 0))
        return chosen;
    std::vector<std::unique_ptr<LevelResampler>> resamplers;  // levels 1..n; not copyable
    for (int j = 1; j <= levels; ++j)
        resamplers.push_back(std::make_unique<LevelResampler>(model.width, model.height, j));
    std::vector<factor::AngularResampler> angular_resamplers;
    for (const factor::AngularLevel& a : angular_levels)
        angular_resamplers.emplace_back(model.sampling, a, model.colour.channels());

    // Per item: ‖y₁‖², and per spatial level j ≥ 1 ‖y₂‖², y₁·y₂; ‖x₂‖², and per angular level
    // m ≥ 1 ‖x₁‖², x₁·x₂ (y₁ = T_u b).
    const int64_t texels = int64_t(model.width) * model.height;
    std::vector<double> y11(items.size()), y22(items.size() * levels), y12(items.size() * levels);
    std::vector<double> x22(items.size()), x11(items.size() * angular), x12(items.size() * angular);
    for (int p = 0; p < 3; ++p) {
        std::vector<size_t> mine;
        for (size_t i = 0; i < items.size(); ++i)
            if (items[i].plane == p) mine.push_back(i);
        if (mine.empty()) continue;
        const int64_t n = int64_t(mine.size());
        // Spatial: columns [0, n) are y₁, then n · levels residuals y₂ (item-major).
        factor::Matrix y(texels, n * (1 + levels));
        parallel_for(0, n * (1 + levels), [&](int64_t col) {
            const Item& item = items[mine[size_t(col < n ? col : (col - n) / levels)]];
            const Eigen::VectorXd b = factors[p].b.col(item.k).cast<double>();
            if (col < n) {
                y.col(col) = b.cast<float>();
                return;
            }
            const LevelResampler& r = *resamplers[size_t((col - n) % levels)];
            y.col(col) = (b - r.upsample(r.downsample(b))).cast<float>();
        });
        if (transforms) transforms->spatial(p).apply(y);
        // Angular: columns [0, n) are x₂, then n · angular residuals x₁ (item-major).
        const int64_t rows = factors[p].a.rows();
        factor::Matrix x(rows, n * (1 + angular));
        parallel_for(0, n * (1 + angular), [&](int64_t col) {
            const Item& item = items[mine[size_t(col < n ? col : (col - n) / angular)]];
            const Eigen::MatrixXd a = factors[p].a.col(item.k).cast<double>();
            if (col < n) {
                x.col(col) = a.cast<float>();
                return;
            }
            const factor::AngularResampler& r = angular_resamplers[size_t((col - n) % angular)];
            x.col(col) = (a - r.upsample(r.downsample(a))).cast<float>();
        });
        if (transforms) transforms->angular(p).apply(x, false);
        for (int64_t m = 0; m < n; ++m) {
            const size_t i = mine[size_t(m)];
            const Eigen::VectorXd y1 = y.col(m).cast<double>(), x2 = x.col(m).cast<double>();
            y11[i] = y1.squaredNorm();
            x22[i] = x2.squaredNorm();
            for (int j = 0; j < levels; ++j) {
                const Eigen::VectorXd y2 = y.col(n + m * levels + j).cast<double>();
                y22[i * levels + j] = y2.squaredNorm();
                y12[i * levels + j] = y1.dot(y2);
            }
            for (int j = 0; j < angular; ++j) {
                const Eigen::VectorXd x1 = x.col(n + m * angular + j).cast<double>();
                x11[i * angular + j] = x1.squaredNorm();
                x12[i * angular + j] = x1.dot(x2);
            }
        }
    }
    auto lost = [&](size_t i, int j, int m) {
        const double s22 = j == 0 ? 0.0 : y22[i * levels + j - 1];
        const double s12 = j == 0 ? 0.0 : y12[i * levels + j - 1];
        const double t11 = m == 0 ? 0.0 : x11[i * angular + m - 1];
        const double t12 = m == 0 ? 0.0 : x12[i * angular + m - 1];
        const double yp = y11[i] - 2 * s12 + s22, yp2 = s12 - s22;  // ‖y′‖², y′·y₂
        return std::max(0.0, t11 * yp + x22[i] * s22 + 2 * t12 * yp2);
    };

    const double weight = options.quality / (1 - options.quality);
    const double floor = 1e-12 * energy;
    double error = energy, quality = 0;
    for (size_t i = 0; i < items.size(); ++i) {
        const double sigma2 = double(items[i].sigma) * items[i].sigma;
        double best = -std::numeric_limits<double>::infinity(), best_error = error;
        for (int m = 0; m <= angular; ++m)
            for (int j = 0; j <= levels; ++j) {
                const double cost = lost(i, j, m);
                const double remaining = std::max(error - (sigma2 - cost), floor);
                const double gain = energy / remaining - 1 - quality;
                if (!(gain > 0)) continue;
                const int64_t rows = m == 0 ? factors[items[i].plane].a.rows()
                                            : angular_resamplers[size_t(m - 1)].coarse_rows();
                const double bytes = double(
                    factor::column_bytes(options.quantization, rows) +
                    factor::column_bytes(options.quantization,
                                         int64_t(model.level_width(j)) * model.level_height(j)));
                const double score = weight * std::log(gain) - std::log(bytes);
                if (score > best) {
                    best = score;
                    chosen[i] = {j, m, cost};
                    best_error = remaining;
                }
            }
        error = best_error;
        quality = energy / error - 1;
    }
    return chosen;
}

}  // namespace

factor::Model factorize(const BtfSource& source, const Options& options, Progress& progress,
                        OmissionReport* report) {
    factor::ColourHandling colour;
    colour.basis = factor::ColourBasis::kLab;
    factor::Model model = factor::model_for(source, colour, kName);
    const factor::SourceRows rows(source, colour, model.groups);
    const CsfTransforms csf(model.sampling, model.width, model.height, options.viewing);
    const Identity identity;
    const factor::Transforms& transforms =
        options.csf ? static_cast<const factor::Transforms&>(csf) : identity;

    factor::SvdOptions svd =
        factor::svd_options(options, options.components, options.subtract_mean);
    svd.transforms = &transforms;
    const std::vector<factor::Svd> planes = factor::randomized_svd(rows, svd, progress);

    std::vector<const factor::Svd*> pointers;
    for (const factor::Svd& plane : planes) pointers.push_back(&plane);
    const std::vector<int> keep = factor::allocate_components(pointers, options.components);
    const std::vector<factor::Factors> factors =
        factor::untransformed_factors(rows, transforms, planes, keep, progress);

    // The kept components in decreasing σ over the planes (the allocation's order).
    std::vector<Item> items;
    for (int p = 0; p < 3; ++p)
        for (int k = 0; k < keep[p]; ++k) items.push_back({p, k, planes[p].sigma[k]});
    std::stable_sort(items.begin(), items.end(),
                     [](const Item& a, const Item& b) { return a.sigma > b.sigma; });
    double energy = 0;
    for (const factor::Svd& plane : planes) energy += plane.sketch_energy;
    const std::vector<factor::AngularLevel> angular_levels =
        options.quality < 1
            ? factor::nested_angular_levels(model.sampling, options.max_angular_level)
            : std::vector<factor::AngularLevel>();
    const std::vector<Choice> choice = choose_levels(items, factors, options.csf ? &csf : nullptr,
                                                     model, angular_levels, options, energy);

    // Blocks per plane, spatial and angular level; each keeps its components in decreasing σ.
    int max_angular = 0;
    model.levels = 1;
    for (const Choice& c : choice) {
        model.levels = std::max(model.levels, c.level + 1);
        max_angular = std::max(max_angular, c.angular);
    }
    model.angular_levels.assign(angular_levels.begin(), angular_levels.begin() + max_angular);
    const int angular = model.angular_count();
    std::vector<std::vector<size_t>> members(size_t(3) * model.levels * angular);
    for (size_t i = 0; i < items.size(); ++i)
        members[(size_t(items[i].plane) * model.levels + choice[i].level) * angular +
                choice[i].angular]
            .push_back(i);
    for (int p = 0; p < 3; ++p)
        for (int j = 0; j < model.levels; ++j) {
            std::unique_ptr<LevelResampler> resampler;
            if (j > 0) resampler = std::make_unique<LevelResampler>(model.width, model.height, j);
            for (int m = 0; m < angular; ++m) {
                const std::vector<size_t>& list =
                    members[(size_t(p) * model.levels + j) * angular + m];
                std::unique_ptr<factor::AngularResampler> angular_resampler;
                if (m > 0)
                    angular_resampler = std::make_unique<factor::AngularResampler>(
                        model.sampling, model.angular_levels[size_t(m - 1)],
                        model.colour.channels());
                factor::Block block;
                block.plane = p;
                block.level = j;
                block.angular = m;
                if (j == 0 && m == 0) block.mean = planes[p].mean;
                const int64_t texels = int64_t(model.level_width(j)) * model.level_height(j);
                block.a.resize(model.block_rows(0, m), int64_t(list.size()));
                block.b.resize(texels, int64_t(list.size()));
                for (size_t c = 0; c < list.size(); ++c) {
                    const Item& item = items[list[c]];
                    if (m == 0)
                        block.a.col(int64_t(c)) = factors[p].a.col(item.k);
                    else
                        block.a.col(int64_t(c)) =
                            angular_resampler->downsample(factors[p].a.col(item.k).cast<double>())
                                .cast<float>();
                    if (j == 0)
                        block.b.col(int64_t(c)) = factors[p].b.col(item.k);
                    else
                        block.b.col(int64_t(c)) =
                            resampler->downsample(factors[p].b.col(item.k).cast<double>())
                                .cast<float>();
                    block.energy.push_back(item.sigma);
                }
                model.blocks.push_back(std::move(block));
            }
        }
    model.validate(kName);
    if (report) {
        report->energy = energy;
        report->components.clear();
        for (size_t i = 0; i < items.size(); ++i)
            report->components.push_back({items[i].plane, items[i].sigma, choice[i].level,
                                          choice[i].angular, choice[i].lost});
    }
    return model;
}

}  // namespace perceptual

namespace {

class PerceptualCodec final : public factor::FactorCodec {
  public:
    std::string_view name() const override { return perceptual::kName; }
    std::string_view description() const override {
        return "factorization in CIELab weighted by the eye's contrast sensitivity (BTF-CIELab)";
    }
    std::vector<ParamInfo> params() const override { return perceptual::schema().infos(); }
    void validate(const Params& params) const override { perceptual::schema().parse(params); }

  protected:
    Result factorize(const BtfSource& source, const Params& params,
                     Progress& progress) const override {
        const perceptual::Options o = perceptual::schema().parse(params);
        Result result;
        result.model = perceptual::factorize(source, o, progress);
        result.params = perceptual::schema().to_json(o);
        result.quantization = o.quantization;
        result.quality = o.coding_quality;
        return result;
    }
};

}  // namespace

const Codec& perceptual_codec() {
    static const PerceptualCodec codec;
    return codec;
}

}  // namespace btf
