// SPDX-License-Identifier: MIT
#include "btf/codecs/lpca/lpca.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <set>

#include "btf/io/function_source.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

using ::testing::HasSubstr;

// `materials` distinct ABRDFs (random per view, light and channel) on an irregular texel map;
// each texel scales its material's ABRDF by 1 ± 10 %: rank 1 per material after centring.
struct Mosaic {
    int size = 12;
    int materials = 3;
    std::vector<int> material;  // per texel
    std::unique_ptr<FunctionSource> source;
};
Mosaic mosaic(int materials, int size, int views, int lights) {
    Mosaic m;
    m.size = size;
    m.materials = materials;
    m.material.resize(size * size);
    for (int t = 0; t < size * size; ++t)
        m.material[t] = std::min(materials - 1, int(test::hash01(t, 7, 7, 7) * materials));
    m.source = std::make_unique<FunctionSource>(
        test::ubo_subset(views, lights), size, size,
        [size, material = m.material](int v, int l, int x, int y) {
            const int k = material[y * size + x];
            const float s = 0.9f + 0.2f * test::hash01(x, y, 11, 0);
            return Rgb{s * test::hash01(v, l, k, 0), s * test::hash01(v, l, k, 1),
                       s * test::hash01(v, l, k, 2)};
        });
    return m;
}

double relative_error(const Material& material, const BtfSource& source) {
    double error = 0, total = 0;
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); ++l) {
            const Image image = source.image(v, l);
            for (int y = 0; y < source.height(); ++y)
                for (int x = 0; x < source.width(); ++x) {
                    const Rgb a = material.eval_sample(x, y, v, l), b = image.rgb(x, y);
                    error +=
                        std::pow(a.r - b.r, 2) + std::pow(a.g - b.g, 2) + std::pow(a.b - b.b, 2);
                    total += double(b.r) * b.r + double(b.g) * b.g + double(b.b) * b.b;
                }
        }
    return std::sqrt(error / total);
}

// True if the labels `a` and `b` define the same partition (equal up to renaming).
bool same_partition(const std::vector<int32_t>& a, const std::vector<int>& b) {
    std::map<int, int> a_to_b, b_to_a;
    for (size_t i = 0; i < a.size(); ++i) {
        if (a_to_b.emplace(a[i], b[i]).first->second != b[i]) return false;
        if (b_to_a.emplace(b[i], a[i]).first->second != a[i]) return false;
    }
    return true;
}

// Points around `centres` (0.1 noise), the i-th around centre (i · 7) mod count.
factor::Matrix blobs(const std::vector<std::pair<float, float>>& centres, int n,
                     std::vector<int>& truth) {
    std::mt19937 rng(3);
    std::normal_distribution<float> noise(0.0f, 0.1f);
    factor::Matrix points(n, 2);
    truth.resize(n);
    for (int i = 0; i < n; ++i) {
        truth[i] = (i * 7) % int(centres.size());
        points(i, 0) = centres[truth[i]].first + noise(rng);
        points(i, 1) = centres[truth[i]].second + noise(rng);
    }
    return points;
}

factor::Matrix rows_of(std::initializer_list<std::pair<float, float>> centres) {
    factor::Matrix m(int(centres.size()), 2);
    int i = 0;
    for (const auto& [x, y] : centres) m.row(i++) << x, y;
    return m;
}

TEST(LpcaKmeans, SeparatesBlobsAndNumbersByFirstPoint) {
    std::vector<int> truth;
    const factor::Matrix points = blobs({{5, 0}, {0, 0}, {0, 5}, {5, 5}}, 200, truth);
    for (uint64_t seed : {1, 2, 3}) {
        const std::vector<int32_t> label = lpca::kmeans(points, 4, 20, seed);
        EXPECT_TRUE(same_partition(label, truth)) << "seed " << seed;
        EXPECT_EQ(label[0], 0);
        EXPECT_EQ(*std::max_element(label.begin(), label.end()), 3);
        EXPECT_EQ(label, lpca::kmeans(points, 4, 20, seed)) << "deterministic";
    }
}

TEST(LpcaKmeans, MoreClustersThanDistinctPointsDropsTheEmptyOnes) {
    factor::Matrix points(30, 3);
    for (int i = 0; i < 30; ++i) points.row(i) << float(i % 3), float(i % 3 == 1), 0.0f;
    const std::vector<int32_t> label = lpca::kmeans(points, 7, 10, 1);
    EXPECT_EQ(*std::max_element(label.begin(), label.end()), 2);
    for (int i = 0; i < 30; ++i) EXPECT_EQ(label[i], label[i % 3]);
    // Fewer points than clusters, and all points equal.
    EXPECT_EQ(lpca::kmeans(points.topRows(2), 5, 10, 1), (std::vector<int32_t>{0, 1}));
    const factor::Matrix same = factor::Matrix::Ones(6, 2);
    EXPECT_EQ(lpca::kmeans(same, 3, 10, 1), std::vector<int32_t>(6, 0));
}

TEST(LpcaKmeans, EmptyClustersAreReseededOrDropped) {
    std::vector<int> truth;
    // A centre no point is near starts empty and takes the farthest point.
    const factor::Matrix two = blobs({{0, 0}, {5, 5}}, 60, truth);
    std::vector<int32_t> label = lpca::lloyd(two, rows_of({{100, 100}, {0, 0}}), 20);
    EXPECT_TRUE(same_partition(label, truth));
    EXPECT_EQ(*std::max_element(label.begin(), label.end()), 1);
    // Two equal centres: the second gets nothing (ties go to the first) and is re-seeded.
    const factor::Matrix three = blobs({{0, 0}, {5, 5}, {10, 0}}, 90, truth);
    label = lpca::lloyd(three, rows_of({{0, 0}, {0, 0}, {5, 5}}), 20);
    EXPECT_TRUE(same_partition(label, truth));
    EXPECT_EQ(*std::max_element(label.begin(), label.end()), 2);
    // Identical points: the clusters that cannot be re-seeded are dropped.
    label = lpca::lloyd(factor::Matrix::Zero(5, 2), rows_of({{0, 0}, {1, 1}, {2, 2}}), 20);
    EXPECT_EQ(label, std::vector<int32_t>(5, 0));
    EXPECT_THAT(test::error_of([&] { lpca::lloyd(two, factor::Matrix::Zero(2, 3), 20); }),
                HasSubstr("dimensions"));
}

TEST(LpcaKmeans, ConvergesToAFixedPointOnDegenerateData) {
    // Many duplicate points and up to as many clusters as points: empty clusters arise and are
    // re-seeded or dropped. The result must be a Lloyd fixed point with min(k, distinct)
    // clusters numbered by their first point.
    std::mt19937 rng(11);
    for (int trial = 0; trial < 200; ++trial) {
        const int n = 1 + int(rng() % 40), clusters = 1 + int(rng() % 12);
        factor::Matrix points(n, 2);
        for (int i = 0; i < n; ++i) points.row(i) << float(rng() % 4), float(rng() % 3);
        std::set<std::pair<float, float>> distinct;
        for (int i = 0; i < n; ++i) distinct.emplace(points(i, 0), points(i, 1));
        const std::vector<int32_t> label = lpca::kmeans(points, clusters, 100, trial);
        ASSERT_EQ(int(label.size()), n);
        int32_t next = 0;
        for (int32_t l : label) {
            ASSERT_LE(l, next) << "trial " << trial;
            if (l == next) ++next;
        }
        EXPECT_EQ(next, std::min<int>(clusters, int(distinct.size()))) << "trial " << trial;
        Eigen::MatrixXd centre = Eigen::MatrixXd::Zero(next, 2);
        Eigen::VectorXd members = Eigen::VectorXd::Zero(next);
        for (int i = 0; i < n; ++i) {
            centre.row(label[i]) += points.row(i).cast<double>();
            members[label[i]] += 1;
        }
        for (int c = 0; c < next; ++c) centre.row(c) /= members[c];
        for (int i = 0; i < n; ++i)
            for (int c = 0; c < next; ++c)
                EXPECT_LE((points.row(i).cast<double>() - centre.row(label[i])).squaredNorm(),
                          (points.row(i).cast<double>() - centre.row(c)).squaredNorm() + 1e-9)
                    << "trial " << trial << " point " << i;
    }
}

TEST(Lpca, ClusterRowsGatherTheClustersColumns) {
    const Mosaic m = mosaic(3, 6, 3, 4);
    std::vector<std::vector<int32_t>> texels = {{0, 5, 7}, {1, 2, 3, 4, 6}, {}};
    for (int t = 8; t < 36; ++t) texels[2].push_back(t);
    factor::ColourHandling colour;
    colour.basis = factor::ColourBasis::kDecorrelated;
    const lpca::ClusterRows rows(*m.source, colour, texels);
    const factor::SourceRows all(*m.source, colour, {{0, 1, 2}});
    ASSERT_EQ(rows.matrices(), 9);
    ASSERT_EQ(rows.batches(), 3);
    std::vector<int64_t> first, all_first;
    std::vector<factor::Matrix> out, all_out;
    for (int b = 0; b < 3; ++b) {
        rows.read(b, first, out);
        all.read(b, all_first, all_out);
        for (int p = 0; p < 3; ++p)
            for (int c = 0; c < 3; ++c) {
                const int i = p * 3 + c;
                EXPECT_EQ(rows.rows(i), all.rows(all.matrix(p, 0)));
                EXPECT_EQ(rows.cols(i), int64_t(texels[c].size()));
                const factor::Matrix& in = all_out[all.matrix(p, 0)];
                EXPECT_EQ(first[i], all_first[all.matrix(p, 0)]);
                ASSERT_EQ(out[i].rows(), in.rows());
                ASSERT_EQ(out[i].cols(), int64_t(texels[c].size()));
                for (size_t j = 0; j < texels[c].size(); ++j)
                    EXPECT_TRUE(out[i].col(j) == in.col(texels[c][j]));
            }
    }
}

TEST(Lpca, ClustersThreeMaterialsExactlyAndReconstructsRankOnePerCluster) {
    const Mosaic m = mosaic(3, 12, 4, 5);
    for (const char* colour : {"rgb", "decorrelated"}) {
        const lpca::Options options = lpca::parse_options(Params(
            {{"clusters", "3"}, {"components", "1"}, {"colour", colour}, {"quantize", "f32"}}));
        const factor::Model model = lpca::factorize(*m.source, options);
        ASSERT_EQ(model.clusters, 3) << colour;
        EXPECT_TRUE(same_partition(model.texel_cluster, m.material)) << colour;
        // rgb: one plane, so one component per cluster. Decorrelated: one component over the
        // three planes cannot hold a rank-1 ABRDF with colour, so only rgb is exact.
        if (std::string(colour) == "rgb") {
            for (const factor::Block& b : model.blocks) EXPECT_EQ(b.components(), 1);
            EXPECT_LT(relative_error(factor::FactorMaterial(model), *m.source), 1e-5);
        }
    }
}

TEST(Lpca, OneClusterIsAGlobalPca) {
    const Mosaic m = mosaic(3, 8, 3, 4);
    const factor::Model model =
        lpca::factorize(*m.source, lpca::parse_options(Params({{"clusters", "1"}})));
    EXPECT_EQ(model.clusters, 1);
    EXPECT_TRUE(model.texel_cluster.empty());
    ASSERT_EQ(model.blocks.size(), 1u);
    EXPECT_EQ(model.blocks[0].components(), 5);
    EXPECT_FALSE(model.blocks[0].mean.empty());
}

TEST(Lpca, MoreClustersLowerTheError) {
    const auto source = test::cached(*synth::make("woven_fabric", 16, test::ubo_subset(8, 8), 2));
    double previous = 1e30;
    for (int clusters : {1, 2, 4, 8}) {
        const lpca::Options options = lpca::parse_options(Params(
            {{"clusters", std::to_string(clusters)}, {"components", "2"}, {"quantize", "f32"}}));
        const factor::Model model = lpca::factorize(*source, options);
        EXPECT_EQ(model.clusters, clusters);
        const double e = relative_error(factor::FactorMaterial(model), *source);
        EXPECT_LT(e, previous) << clusters << " clusters";
        previous = e;
    }
    // A mosaic of six materials: six clusters of rank 1 each are nearly exact.
    const Mosaic m = mosaic(6, 16, 4, 4);
    const double e = relative_error(
        factor::FactorMaterial(lpca::factorize(
            *m.source, lpca::parse_options(Params({{"clusters", "6"}, {"components", "1"}})))),
        *m.source);
    EXPECT_LT(e, 1e-3);
}

TEST(Lpca, PackageRoundTrip) {
    const Mosaic m = mosaic(3, 10, 3, 4);
    const Codec& codec = find_codec("lpca");
    EXPECT_EQ(&codec, &lpca_codec());
    const Params params({{"clusters", "3"}, {"components", "2"}, {"quantize", "f32"}});
    Package package = codec.encode(*m.source, params);
    EXPECT_EQ(package.codec(), "lpca");
    EXPECT_EQ(package.header.at("params").at("clusters"), 3);
    const std::vector<uint8_t> bytes = encode_package(package);
    const std::unique_ptr<Material> decoded = open_material(decode_package(bytes, "test"));
    const factor::FactorMaterial direct(lpca::factorize(*m.source, lpca::parse_options(params)));
    for (int v = 0; v < 3; ++v)
        for (int l = 0; l < 4; ++l)
            for (int y = 0; y < 10; ++y)
                for (int x = 0; x < 10; ++x) {
                    const Rgb a = decoded->eval_sample(x, y, v, l);
                    const Rgb b = direct.eval_sample(x, y, v, l);
                    EXPECT_NEAR(a.r, b.r, 1e-6);
                    EXPECT_NEAR(a.g, b.g, 1e-6);
                    EXPECT_NEAR(a.b, b.b, 1e-6);
                }
    // Deterministic: the same bytes again.
    Package again = codec.encode(*m.source, params);
    EXPECT_EQ(encode_package(again), bytes);
}

TEST(Lpca, ParametersAreChecked) {
    const Codec& codec = lpca_codec();
    const Mosaic m = mosaic(2, 4, 2, 2);
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(*m.source, Params({{"cluster", "3"}}));
                }),
                HasSubstr("unknown parameter 'cluster'"));
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(*m.source, Params({{"clusters", "0"}}));
                }),
                HasSubstr("clusters"));
    EXPECT_THAT(test::error_of([&] {
                    codec.encode(*m.source, Params({{"projection", "x"}}));
                }),
                HasSubstr("projection"));
    std::vector<std::string> names;
    for (const ParamInfo& info : codec.params()) names.push_back(info.name);
    for (const char* name :
         {"clusters", "components", "colour", "quantize", "iterations", "seed", "projection"})
        EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
}

}  // namespace
}  // namespace btf
