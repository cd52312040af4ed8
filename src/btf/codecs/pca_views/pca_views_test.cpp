// SPDX-License-Identifier: MIT
#include "btf/codecs/pca_views/pca_views.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <random>

#include "btf/io/function_source.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

using ::testing::HasSubstr;

// Values of full rank: every angular sample independent.
FunctionSource random_source(int views, int lights, int size) {
    return FunctionSource(test::ubo_subset(views, lights), size, size,
                          [](int v, int l, int x, int y) {
                              return Rgb{test::hash01(v, l, x, y), test::hash01(v, l, x, y + 1000),
                                         test::hash01(v, l, x, y + 2000)};
                          });
}

std::unique_ptr<FunctionSource> synthetic(int views, int lights) {
    return test::cached(*synth::make("knitted_wool", 16, test::ubo_subset(views, lights), 3));
}

// Σ (decoded − source)² over every sample and channel, and Σ source².
struct Error2 {
    double error = 0, total = 0;
    double relative() const { return std::sqrt(error / total); }
};
Error2 squared_error(const Material& material, const BtfSource& source) {
    Error2 e;
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); ++l) {
            const Image image = source.image(v, l);
            for (int y = 0; y < source.height(); ++y)
                for (int x = 0; x < source.width(); ++x) {
                    const Rgb a = material.eval_sample(x, y, v, l), b = image.rgb(x, y);
                    e.error +=
                        std::pow(a.r - b.r, 2) + std::pow(a.g - b.g, 2) + std::pow(a.b - b.b, 2);
                    e.total += double(b.r) * b.r + double(b.g) * b.g + double(b.b) * b.b;
                }
        }
    return e;
}

double angle_deg(const Vec3& a, const Vec3& b) {
    return degrees(std::acos(std::clamp(dot(normalize(a), normalize(b)), -1.0, 1.0)));
}

void expect_partition(const std::vector<std::vector<int>>& groups, int views, int k) {
    std::vector<int> seen(views, 0);
    const int count = (views + std::min(k, views) - 1) / std::min(k, views);
    ASSERT_EQ(static_cast<int>(groups.size()), count) << "k " << k;
    size_t smallest = views, largest = 0;
    for (const auto& g : groups) {
        smallest = std::min(smallest, g.size());
        largest = std::max(largest, g.size());
        for (int v : g) {
            ASSERT_GE(v, 0);
            ASSERT_LT(v, views);
            ++seen[v];
        }
    }
    EXPECT_LE(largest, size_t(k)) << "k " << k;
    EXPECT_LE(largest - smallest, 1u) << "k " << k;
    for (int v = 0; v < views; ++v) EXPECT_EQ(seen[v], 1) << "view " << v << ", k " << k;
}

TEST(PcaViewsGrouping, EveryViewInExactlyOneGroup) {
    for (const DirectionSet* set : {&DirectionSet::ubo81(), &DirectionSet::dome151()})
        for (int k : {1, 2, 3, 4, 5, 7, 10, 80, 81, 151, 1000}) {
            const auto groups = pca_views::group_views(*set, k);
            expect_partition(groups, set->size(), k);
            for (const auto& g : groups) EXPECT_TRUE(std::is_sorted(g.begin(), g.end()));
            EXPECT_TRUE(std::is_sorted(groups.begin(), groups.end()));
            EXPECT_EQ(groups, pca_views::group_views(*set, k)) << "deterministic";
        }
}

TEST(PcaViewsGrouping, FindsTightClustersInShuffledOrder) {
    // Five clusters of three directions 2° apart, 30°+ between clusters, listed shuffled.
    const std::vector<Direction> centres = {
        Direction::from_degrees(0, 0), Direction::from_degrees(45, 0),
        Direction::from_degrees(45, 120), Direction::from_degrees(45, 240),
        Direction::from_degrees(75, 60)};
    std::vector<Direction> directions;
    std::vector<int> cluster_of;
    for (int c = 0; c < 5; ++c)
        for (int i = 0; i < 3; ++i) {
            directions.push_back(Direction::from_degrees(centres[c].theta_deg() + 2.0 * (i == 1),
                                                         centres[c].phi_deg() + 2.0 * (i == 2)));
            cluster_of.push_back(c);
        }
    std::vector<int> order(directions.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), std::mt19937(5));
    std::vector<Direction> shuffled;
    std::vector<int> shuffled_cluster;
    for (int i : order) {
        shuffled.push_back(directions[i]);
        shuffled_cluster.push_back(cluster_of[i]);
    }
    const auto groups = pca_views::group_views(DirectionSet("clusters", shuffled), 3);
    ASSERT_EQ(groups.size(), 5u);
    for (const auto& g : groups) {
        ASSERT_EQ(g.size(), 3u);
        for (int v : g) EXPECT_EQ(shuffled_cluster[v], shuffled_cluster[g[0]]);
    }
}

// Largest angle between a view and its group's mean direction, over all groups.
double widest_spread(const DirectionSet& views, const std::vector<std::vector<int>>& groups) {
    double widest = 0;
    for (const auto& g : groups) {
        Vec3 centre;
        for (int v : g) centre += views.vector(v);
        for (int v : g) widest = std::max(widest, angle_deg(centre, views.vector(v)));
    }
    return widest;
}

TEST(PcaViewsGrouping, GroupsAreNeighbourhoods) {
    // Neighbouring UBO81 views are 15° apart (rings 15° apart, ≤ 15° between ring neighbours),
    // dome151 views about 10°: a group of three neighbours lies within one step of its centre.
    // Grouping by index (along the rings) is the comparison that must be beaten.
    for (const auto& [set, step] :
         {std::pair{&DirectionSet::ubo81(), 15.0}, std::pair{&DirectionSet::dome151(), 10.0}}) {
        const auto groups = pca_views::group_views(*set, 3);
        EXPECT_LE(widest_spread(*set, groups), step + 0.1) << set->name();
        std::vector<std::vector<int>> by_index(groups.size());
        for (int v = 0; v < set->size(); ++v) by_index[v / 3].push_back(v);
        double mean = 0, mean_by_index = 0;
        for (size_t g = 0; g < groups.size(); ++g) {
            mean += widest_spread(*set, {groups[g]});
            mean_by_index += widest_spread(*set, {by_index[g]});
        }
        EXPECT_LT(mean, 0.8 * mean_by_index) << set->name();
    }
}

TEST(PcaViews, FullRankPerViewIsExact) {
    const int lights = 4;
    const FunctionSource source = random_source(5, lights, 8);
    for (const auto& [colour, log] : {std::pair{"rgb", "false"}, std::pair{"decorrelated", "false"},
                                      std::pair{"rgb", "true"}}) {
        const pca_views::Options options =
            pca_views::parse_options(Params({{"views-per-group", "1"},
                                             {"components", std::to_string(3 * lights)},
                                             {"colour", colour},
                                             {"log", log},
                                             {"quantize", "f32"}}));
        const factor::Model model = pca_views::factorize(source, options);
        ASSERT_EQ(model.groups.size(), 5u);
        for (const factor::Block& block : model.blocks) EXPECT_FALSE(block.mean.empty());
        const factor::FactorMaterial material(model);
        double largest = 0;
        for (int v = 0; v < source.num_views(); ++v)
            for (int l = 0; l < lights; ++l)
                for (int y = 0; y < 8; ++y)
                    for (int x = 0; x < 8; ++x) {
                        const Rgb a = material.eval_sample(x, y, v, l);
                        const Rgb b = source.value(v, l, x, y);
                        largest =
                            std::max({largest, double(std::abs(a.r - b.r)),
                                      double(std::abs(a.g - b.g)), double(std::abs(a.b - b.b))});
                    }
        EXPECT_LT(largest, 2e-5) << colour << ", log " << log;
    }
}

TEST(PcaViews, MoreComponentsLowerTheError) {
    const auto source = synthetic(9, 8);
    for (int k : {1, 3}) {
        double previous = 1e30;
        for (int c : {1, 2, 4, 8, 16}) {
            const pca_views::Options options =
                pca_views::parse_options(Params({{"views-per-group", std::to_string(k)},
                                                 {"components", std::to_string(c)},
                                                 {"quantize", "f32"}}));
            const double e =
                squared_error(factor::FactorMaterial(pca_views::factorize(*source, options)),
                              *source)
                    .relative();
            EXPECT_LT(e, previous) << "k " << k << ", C " << c;
            previous = e;
        }
        EXPECT_LT(previous, 0.05) << "k " << k;
    }
}

TEST(PcaViews, FewerViewsPerGroupLowerTheErrorAtEqualComponents) {
    // Each group has its own C components: smaller groups spend more of them per view.
    const auto source = synthetic(9, 8);
    double previous = 0;
    for (int k : {1, 3, 9}) {
        const pca_views::Options options = pca_views::parse_options(Params(
            {{"views-per-group", std::to_string(k)}, {"components", "4"}, {"quantize", "f32"}}));
        const double e =
            squared_error(factor::FactorMaterial(pca_views::factorize(*source, options)), *source)
                .relative();
        EXPECT_GT(e, previous) << "k " << k;
        previous = e;
    }
}

TEST(PcaViews, AllViewsIsOneOptimalPca) {
    const auto source = synthetic(7, 6);
    const int components = 6;
    auto model_for = [&](int k) {
        return pca_views::factorize(
            *source, pca_views::parse_options(Params({{"views-per-group", std::to_string(k)},
                                                      {"components", std::to_string(components)},
                                                      {"power-iterations", "4"}})));
    };
    const factor::Model all = model_for(7);
    ASSERT_EQ(all.groups.size(), 1u);
    EXPECT_EQ(all.groups[0], (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
    const factor::Model more = model_for(1000);
    ASSERT_EQ(more.groups, all.groups);
    ASSERT_EQ(more.blocks.size(), 1u);
    EXPECT_EQ(more.blocks[0].a, all.blocks[0].a);
    EXPECT_EQ(more.blocks[0].b, all.blocks[0].b);

    // The whole BTF matrix (rows: view × light × channel, columns: texels) through its exact
    // SVD: the codec's error is the Eckart–Young optimum of the centred matrix.
    const factor::SourceRows rows(*source, {}, all.groups);
    factor::Matrix matrix(rows.rows(0), rows.cols(0));
    std::vector<int64_t> first;
    std::vector<factor::Matrix> batch;
    for (int b = 0; b < rows.batches(); ++b) {
        rows.read(b, first, batch);
        matrix.middleRows(first[0], batch[0].rows()) = batch[0];
    }
    const factor::Svd exact = factor::exact_svd(matrix, components, true);
    const double optimum = exact.total_energy - exact.sigma.cast<double>().squaredNorm();
    const double error = squared_error(factor::FactorMaterial(all), *source).error;
    EXPECT_NEAR(error, optimum, 0.01 * optimum);
    for (int k = 0; k < components; ++k)
        EXPECT_NEAR(all.blocks[0].energy[k], exact.sigma[k], 1e-3 * exact.sigma[0]) << k;
}

TEST(PcaViews, PackageRoundTrip) {
    const auto source = synthetic(6, 5);
    const Codec& codec = find_codec("pca-views");
    EXPECT_EQ(&codec, &pca_views_codec());
    const Params params({{"views-per-group", "2"}, {"components", "3"}, {"quantize", "f32"}});
    Package package = codec.encode(*source, params);
    EXPECT_EQ(package.codec(), "pca-views");
    EXPECT_EQ(package.header.at("params").at("views-per-group"), 2);
    EXPECT_EQ(package.header.at("params").at("colour"), "rgb");

    const std::vector<uint8_t> bytes = encode_package(package);
    const std::unique_ptr<Material> decoded = open_material(decode_package(bytes, "test"));
    const factor::FactorMaterial direct(
        pca_views::factorize(*source, pca_views::parse_options(params)));
    for (int v = 0; v < source->num_views(); ++v)
        for (int l = 0; l < source->num_lights(); ++l)
            for (int y = 0; y < 16; y += 3)
                for (int x = 0; x < 16; x += 5) {
                    const Rgb a = decoded->eval_sample(x, y, v, l);
                    const Rgb b = direct.eval_sample(x, y, v, l);
                    EXPECT_NEAR(a.r, b.r, 1e-6);
                    EXPECT_NEAR(a.g, b.g, 1e-6);
                    EXPECT_NEAR(a.b, b.b, 1e-6);
                }

    // f16 storage: the same material within half-float precision.
    Package half = codec.encode(*source, Params({{"views-per-group", "2"}, {"components", "3"}}));
    EXPECT_LT(half.file_bytes, package.file_bytes);
    const auto f16 = codec.open(half);
    const double e32 = squared_error(direct, *source).relative();
    const double e16 = squared_error(*f16, *source).relative();
    EXPECT_NEAR(e16, e32, 0.01 * e32);

    // Coded storage (each group's eigen-textures DCT-coded): through bytes, smaller than f16, and
    // nearer the unquantized error at a higher quality.
    double previous = INFINITY;
    for (const char* quality : {"70", "90"}) {
        Package coded = codec.encode(*source, Params({{"views-per-group", "2"},
                                                      {"components", "3"},
                                                      {"quantize", "coded"},
                                                      {"quality", quality}}));
        const std::vector<uint8_t> coded_bytes = encode_package(coded);
        EXPECT_LT(coded_bytes.size(), encode_package(half).size()) << quality;
        const auto from_bytes = open_material(decode_package(coded_bytes, "coded"));
        const double ec = squared_error(*from_bytes, *source).relative();
        EXPECT_GE(ec, e32 * 0.999) << quality;
        EXPECT_LT(ec, previous) << quality;
        previous = ec;
    }
    EXPECT_LT(previous, 1.1 * e32);
}

TEST(PcaViews, DecorrelatedColourSharesComponentsAcrossPlanes) {
    const auto source = synthetic(6, 5);
    const factor::Model model = pca_views::factorize(
        *source, pca_views::parse_options(Params(
                     {{"views-per-group", "3"}, {"components", "5"}, {"colour", "decorrelated"}})));
    ASSERT_EQ(model.groups.size(), 2u);
    ASSERT_EQ(model.blocks.size(), 6u);
    for (int g = 0; g < 2; ++g) {
        int total = 0;
        for (int p = 0; p < 3; ++p) total += model.blocks[model.block_index(p, g, 0)].components();
        EXPECT_EQ(total, 5) << "group " << g;
        // Luminance carries most energy in a grey-ish material: it gets the most components.
        EXPECT_GE(model.blocks[model.block_index(0, g, 0)].components(), 2);
    }
}

TEST(PcaViews, ParametersAreChecked) {
    const Codec& codec = pca_views_codec();
    const auto source = random_source(2, 2, 4);
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(source, Params({{"component", "8"}}));
                }),
                HasSubstr("unknown parameter 'component'"));
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(source, Params({{"colour", "cmyk"}}));
                }),
                HasSubstr("colour"));
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(source, Params({{"views-per-group", "0"}}));
                }),
                HasSubstr("views-per-group"));
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(source, Params({{"quantize", "f8"}}));
                }),
                HasSubstr("quantize"));
    std::vector<std::string> names;
    for (const ParamInfo& info : codec.params()) names.push_back(info.name);
    for (const char* name : {"views-per-group", "components", "colour", "log", "quantize",
                             "power-iterations", "oversampling", "seed"})
        EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
}

}  // namespace
}  // namespace btf
