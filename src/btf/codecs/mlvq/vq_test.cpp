// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/vq.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "btf/testing/support.h"
#include "btf/util/parallel.h"

namespace btf::mlvq {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

CodebookOptions options(std::vector<uint32_t> dims, Kind kind, Measure measure, double threshold,
                        uint32_t channels = 1) {
    CodebookOptions o;
    o.name = "T";
    o.layout.dims = std::move(dims);
    o.layout.channels = channels;
    o.kind = kind;
    o.measure = measure;
    o.threshold = threshold;
    return o;
}

// A list of vectors.
using Vectors = std::vector<std::vector<float>>;

Vectors uniform_vectors(size_t count, size_t length, uint64_t seed, float lo = 0, float hi = 1) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uni(lo, hi);
    Vectors out(count, std::vector<float>(length));
    for (auto& v : out)
        for (float& x : v) x = uni(rng);
    return out;
}

// Apparent-BRDF-like slices: per channel, a smooth diffuse term plus a specular lobe over the
// angular grid (1-D or 2-D), the parameters drawn around a few material "clusters", each vector
// at its own brightness (so luminance normalization matters) with a little noise. Chromaticity
// channels are small offsets around a cluster colour.
Vectors btf_like(size_t count, const Layout& layout, uint64_t seed, int clusters = 6) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0, 1);
    std::normal_distribution<double> gauss(0, 1);
    struct Cluster {
        double diffuse, spec, width, centre_a, centre_b, cb, cr;
    };
    std::vector<Cluster> cs;
    for (int c = 0; c < clusters; ++c)
        cs.push_back({0.2 + 0.8 * uni(rng), 2 * uni(rng), 0.1 + 0.4 * uni(rng),
                      0.4 * uni(rng) - 0.2, 0.4 * uni(rng) - 0.2, 0.2 * uni(rng) - 0.1,
                      0.2 * uni(rng) - 0.1});
    const uint32_t na = layout.dims.size() > 1 ? layout.dims[0] : 1;
    const uint32_t nb = layout.dims.back();
    const size_t nc = layout.channel_size();
    Vectors out(count, std::vector<float>(layout.size()));
    for (auto& v : out) {
        const Cluster& c = cs[rng() % cs.size()];
        const double brightness = 0.05 + 2 * uni(rng);
        const double width = c.width * (1 + 0.2 * gauss(rng));
        const double ca = c.centre_a + 0.05 * gauss(rng), cb = c.centre_b + 0.05 * gauss(rng);
        const double spec = c.spec * (1 + 0.3 * gauss(rng));
        for (uint32_t a = 0; a < na; ++a)
            for (uint32_t b = 0; b < nb; ++b) {
                const double x = na > 1 ? -1 + 2.0 * a / (na - 1) : 0;
                const double y = -1 + 2.0 * b / (nb - 1);
                const double cosine = std::max(0.0, 1 - 0.5 * (x * x + y * y));
                const double lobe =
                    std::exp(-((x - ca) * (x - ca) + (y - cb) * (y - cb)) / (width * width));
                const double lum = c.diffuse * cosine + spec * lobe + 0.01 * gauss(rng);
                const size_t i = size_t(a) * nb + b;
                v[i] = float(brightness * std::max(0.0, lum));
                for (uint32_t ch = 1; ch < layout.channels; ++ch)
                    v[ch * nc + i] =
                        float((ch == 1 ? c.cb : c.cr) + 0.02 * gauss(rng) + 0.05 * lobe);
            }
    }
    return out;
}

Codebook filled(const CodebookOptions& o, const Vectors& vectors) {
    Codebook book(o);
    for (const auto& v : vectors) book.add(v);
    return book;
}

// find() against the reference for every query: same index, same error to the bit.
void expect_same_as_brute_force(const Codebook& book, const Vectors& queries, double threshold) {
    for (size_t i = 0; i < queries.size(); ++i) {
        const Match fast = book.find(queries[i], threshold);
        const Match ref = book.find_brute_force(queries[i], threshold);
        ASSERT_EQ(fast.index, ref.index) << "query " << i << " threshold " << threshold;
        ASSERT_EQ(fast.error, ref.error) << "query " << i;
        ASSERT_EQ(fast.scale, ref.scale) << "query " << i;
    }
}

// A growing code-book (find_or_add) against one grown with brute-force searches: the same
// code-vectors in the same order and the same answers.
void expect_same_growth(const CodebookOptions& o, const Vectors& stream) {
    Codebook fast(o), ref(o);
    for (size_t i = 0; i < stream.size(); ++i) {
        const Match a = fast.find_or_add(stream[i]);
        Match b = ref.find_brute_force(stream[i], o.threshold);
        if (!b) b = ref.add(stream[i]);
        ASSERT_EQ(a.index, b.index) << "vector " << i;
        ASSERT_EQ(a.added, b.added) << "vector " << i;
        ASSERT_EQ(a.error, b.error) << "vector " << i;
    }
    ASSERT_EQ(fast.size(), ref.size());
}

// ---- options and inputs ----------------------------------------------------------------------

TEST(MlvqVq, RejectsBadOptionsWithOneClearLine) {
    auto o = options({11}, Kind::luminance, Measure::mse, 0.1);
    o.layout.dims = {};
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: the layout has no dimensions");
    o = options({11, 0}, Kind::luminance, Measure::mse, 0.1);
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: a dimension of the layout is 0");
    o = options({11}, Kind::luminance, Measure::mse, -1);
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: threshold must be ≥ 0, not -1");
    o = options({11}, Kind::luminance, Measure::mse, std::nan(""));
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: threshold must be ≥ 0, not nan");
    o = options({11}, Kind::luminance, Measure::mssim, 0.1);
    o.ssim.percentile = 0;
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: SSIM percentile must be in (0, 100], not 0");
    o = options({11}, Kind::luminance, Measure::mssim, 0.1);
    o.ssim.dynamic_range = 0;
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: SSIM dynamic range must be positive, not 0");
    o = options({11}, Kind::luminance, Measure::mse, 0.1, 0);
    EXPECT_EQ(test::error_of([&] { Codebook b(o); }),
              "mlvq code-book T: the layout has 0 channels");
}

TEST(MlvqVq, RejectsBadQueries) {
    Codebook book(options({4}, Kind::chromaticity, Measure::mse, 0.1));
    const std::vector<float> short_query(3, 0.5f);
    EXPECT_EQ(test::error_of([&] { book.find(short_query); }),
              "mlvq code-book T: query has 3 values, expected 4");
    std::vector<float> bad = {0, 1, std::nanf(""), 0};
    EXPECT_EQ(test::error_of([&] { book.find_or_add(bad); }),
              "mlvq code-book T: query value 2 is not finite (nan)");
    EXPECT_EQ(book.size(), 0u);
    EXPECT_EQ(test::error_of([&] { book.find_batch(std::vector<float>(6, 0.f)); }),
              "mlvq code-book T: batch of 6 values is not a whole number of 4-value queries");
    EXPECT_EQ(test::error_of([&] { book.vector(0); }),
              "mlvq code-book T: no code-vector 0 (size 0)");
}

// ---- the threshold rule and luminance normalization ------------------------------------------

TEST(MlvqVq, EmptyCodebookFindsNothingAndGrowsFromTheFirstQuery) {
    for (Measure measure : {Measure::mse, Measure::mssim}) {
        Codebook book(options({11}, Kind::luminance, measure, kInf));
        const std::vector<float> v = uniform_vectors(1, 11, 1)[0];
        EXPECT_FALSE(book.find(v));
        EXPECT_FALSE(book.find_brute_force(v, kInf));
        EXPECT_TRUE(book.find_batch(v).size() == 1 && !book.find_batch(v)[0]);
        const Match m = book.find_or_add(v);
        EXPECT_TRUE(m.added);
        EXPECT_EQ(m.index, 0u);
        EXPECT_EQ(book.size(), 1u);
        const Match again = book.find_or_add(v);
        EXPECT_FALSE(again.added);
        EXPECT_EQ(again.index, 0u);
    }
}

TEST(MlvqVq, LuminanceIsStoredAsAUnitSumPdfWithItsNormAsTheScale) {
    Codebook book(options({5}, Kind::luminance, Measure::mse, 0));
    const std::vector<float> v = {1, 2, 3, 4, 0};
    const Match m = book.add(v);
    EXPECT_DOUBLE_EQ(m.scale, 10);
    double sum = 0;
    for (float x : book.vector(0)) sum += x;
    EXPECT_NEAR(sum, 1, 1e-6);
    EXPECT_FLOAT_EQ(book.vector(0)[3], 0.4f);
    // Any multiple is the same PDF: an exact match with its own scale (threshold 0).
    const std::vector<float> tripled = {3, 6, 9, 12, 0};
    const Match t = book.find(tripled);
    ASSERT_TRUE(t);
    EXPECT_EQ(t.index, 0u);
    EXPECT_DOUBLE_EQ(t.scale, 30);
    EXPECT_EQ(t.error, 0);
    // The L1 norm: a negative value counts with its magnitude.
    const Match n = book.add(std::vector<float>{-1, 1, 0, 0, 0});
    EXPECT_DOUBLE_EQ(n.scale, 2);
    EXPECT_FLOAT_EQ(book.vector(1)[0], -0.5f);
    // A black slice is the uniform PDF with scale 0, and any code-vector reproduces it exactly.
    const std::vector<float> black(5, 0.f);
    const Match z = book.find(black);
    ASSERT_TRUE(z);
    EXPECT_EQ(z.index, 0u);
    EXPECT_EQ(z.scale, 0);
    EXPECT_EQ(z.error, 0);
    Codebook empty(options({5}, Kind::luminance, Measure::mse, 0));
    const Match u = empty.find_or_add(black);
    EXPECT_TRUE(u.added);
    EXPECT_EQ(u.scale, 0);
    for (float x : empty.vector(0)) EXPECT_FLOAT_EQ(x, 0.2f);
}

TEST(MlvqVq, ChromaticityIsComparedAsItIs) {
    Codebook book(options({2}, Kind::chromaticity, Measure::mse, 0.01));
    book.add(std::vector<float>{0.1f, -0.2f});
    EXPECT_FLOAT_EQ(book.vector(0)[1], -0.2f);
    const Match m = book.find(std::vector<float>{0.2f, -0.2f});  // MSE 0.005
    ASSERT_TRUE(m);
    EXPECT_EQ(m.scale, 1);
    EXPECT_NEAR(m.error, 0.005, 1e-7);
    EXPECT_FALSE(book.find(std::vector<float>{0.1f, 0.0f}));  // MSE 0.02
}

// The guarantee the encoder builds on: every query of a grown code-book is reconstructed (scale ×
// code-vector) within the threshold, and queries that match are never added.
TEST(MlvqVq, MseThresholdBoundsTheReconstructionError) {
    const Layout layout{{11}, 1};
    const double threshold = 1e-3;
    Codebook book(options({11}, Kind::luminance, Measure::mse, threshold));
    const Vectors data = btf_like(3000, layout, 7);
    size_t added = 0;
    for (const auto& v : data) {
        const Match m = book.find_or_add(v);
        added += m.added;
        const auto c = book.vector(m.index);
        double mse = 0;
        for (size_t i = 0; i < 11; ++i) {
            const double d = double(v[i]) - m.scale * double(c[i]);
            mse += d * d;
        }
        mse /= 11;
        EXPECT_NEAR(mse, m.error, 1e-9 + 1e-5 * mse);
        EXPECT_LE(mse, threshold * (1 + 1e-5));
    }
    EXPECT_EQ(added, book.size());
    EXPECT_LT(book.size(), data.size() / 3);  // the slices do share code-vectors
    // A larger threshold (training step 2) matches more.
    const Vectors fresh = btf_like(500, layout, 8);
    size_t strict = 0, loose = 0;
    for (const auto& v : fresh) strict += bool(book.find(v));
    book.set_threshold(2.5 * threshold);
    for (const auto& v : fresh) loose += bool(book.find(v));
    EXPECT_GT(loose, strict);
}

// ---- the mse index is exact ------------------------------------------------------------------

TEST(MlvqVq, MseIndexEqualsBruteForceOnUniformData) {
    for (size_t length : {11u, 121u}) {
        const auto o = options({uint32_t(length)}, Kind::chromaticity, Measure::mse, 0);
        const Vectors queries = uniform_vectors(150, length, 2);
        for (size_t count : {0u, 1u, 63u, 64u, 65u, 700u}) {
            const Codebook book = filled(o, uniform_vectors(count, length, 3));
            // Thresholds from nothing to everything, via typical nearest distances.
            for (double t : {0.0, 0.02, 0.05, 0.08, kInf})
                expect_same_as_brute_force(book, queries, t);
        }
    }
}

TEST(MlvqVq, MseIndexEqualsBruteForceOnClusteredSlices) {
    for (const Layout& layout : {Layout{{11}, 1}, Layout{{11, 11}, 1}}) {
        const auto o = options(layout.dims, Kind::luminance, Measure::mse, 0);
        const Codebook book = filled(o, btf_like(2000, layout, 4));
        const Vectors queries = btf_like(200, layout, 5);
        for (double t : {0.0, 1e-5, 1e-4, 1e-3, 1e-2, kInf})
            expect_same_as_brute_force(book, queries, t);
    }
}

TEST(MlvqVq, MseIndexEqualsBruteForceWithChromaticityChannels) {
    // Luminance scaled by s², chromaticity as it is: the weighted bound of the index.
    const Layout layout{{11}, 3};
    auto o = options(layout.dims, Kind::luminance, Measure::mse, 0, 3);
    const Codebook book = filled(o, btf_like(1500, layout, 6));
    Vectors queries = btf_like(200, layout, 7);
    for (size_t i = 0; i < 11; ++i) queries[0][i] = 0;  // black luminance, colour left
    for (double t : {0.0, 1e-4, 1e-3, 1e-2, kInf}) expect_same_as_brute_force(book, queries, t);
}

TEST(MlvqVq, MseIndexEqualsBruteForceForLongVectorsAndWideSignatures) {
    // 200 values: the principal subspace comes from the Gram matrix while the code-book is
    // smaller than 200 (and index_dims larger than that sample), from the covariance later.
    const Layout layout{{20, 10}, 1};
    auto o = options(layout.dims, Kind::luminance, Measure::mse, 2e-4);
    for (uint32_t dims : {1u, 8u, 100u}) {
        o.index_dims = dims;
        expect_same_growth(o, btf_like(600, layout, 8));
    }
}

TEST(MlvqVq, GrowingCodebookEqualsBruteForceGrowth) {
    // Tree rebuilds, refits at 64, 256, 1024 and the scanned tail all on the way.
    expect_same_growth(options({11}, Kind::luminance, Measure::mse, 2e-4),
                       btf_like(6000, Layout{{11}, 1}, 9));
    expect_same_growth(options({11, 11}, Kind::luminance, Measure::mse, 1e-5),
                       btf_like(2500, Layout{{11, 11}, 1}, 10));
    expect_same_growth(options({2}, Kind::chromaticity, Measure::mse, 1e-4),
                       uniform_vectors(3000, 2, 11, -0.5f, 0.5f));
}

TEST(MlvqVq, TiesGoToTheLowestIndex) {
    // Far-away random entries, two planted at exactly the same distance from q (±0.25 along one
    // axis) and four copies of one entry; enough of them for the index to be used.
    const size_t length = 4;
    Vectors entries = uniform_vectors(120, length, 12, 0.9f, 1.0f);
    const std::vector<float> q(length, 0.5f);
    entries[70] = entries[90] = q;
    entries[70][0] = 0.25f;
    entries[90][0] = 0.75f;
    const std::vector<float> dup = entries[5];
    entries[80] = entries[85] = entries[99] = dup;
    for (Measure measure : {Measure::mse, Measure::mssim}) {
        auto o = options({uint32_t(length)}, Kind::chromaticity, measure, kInf);
        o.ssim.radius = 1;
        const Codebook book = filled(o, entries);
        const Match m = book.find(q);
        const Match ref = book.find_brute_force(q, kInf);
        EXPECT_EQ(m.index, ref.index);
        EXPECT_EQ(m.error, ref.error);
        if (measure == Measure::mse) {
            EXPECT_EQ(m.index, 70u);
            EXPECT_EQ(m.error, 0.0625 / length);
        }
        EXPECT_EQ(book.find(dup).index, 5u);
        EXPECT_EQ(book.find_brute_force(dup, kInf).index, 5u);
    }
    // Luminance duplicates are scaled copies.
    Vectors slices = btf_like(100, Layout{{11}, 1}, 13);
    std::vector<float> doubled = slices[10];
    for (float& x : doubled) x *= 2;
    slices[40] = doubled;
    slices[60] = slices[10];
    const Codebook book = filled(options({11}, Kind::luminance, Measure::mse, 0), slices);
    const Match d = book.find(slices[60]);
    EXPECT_EQ(d.index, 10u);
    EXPECT_EQ(d.error, 0);
}

TEST(MlvqVq, IndexPrunesMostComparisonsOnClusteredSlices) {
    const Layout layout{{11, 11}, 1};
    Codebook book(options(layout.dims, Kind::luminance, Measure::mse, 2e-5));
    for (const auto& v : btf_like(6000, layout, 14)) book.find_or_add(v);
    book.rebuild_index();
    ASSERT_GT(book.size(), 500u);
    SearchStats stats;
    for (const auto& v : btf_like(300, layout, 15)) book.find(v, 2e-5, &stats);
    EXPECT_EQ(stats.searches, 300u);
    // Measured 0.18 % and 0.5 %.
    EXPECT_LT(double(stats.compared), 0.01 * double(stats.codebook))
        << stats.compared << " of " << stats.codebook;
    EXPECT_LT(double(stats.bounded), 0.05 * double(stats.codebook))
        << stats.bounded << " of " << stats.codebook;
}

TEST(MlvqVq, MssimIndexAndFilterPruneMostComparisons) {
    // 1-D slices of 11 (k = 0): the range query over the local means and the per-value
    // luminance test leave few code-vectors for the windowed comparison (these noisy slices are
    // harder than rendered ones: bench/mlvq_vq_bench.cpp).
    const Layout layout{{11}, 1};
    const double t = 0.003;
    Codebook book(options(layout.dims, Kind::luminance, Measure::mssim, t));
    for (const auto& v : btf_like(4000, layout, 26)) book.find_or_add(v);
    book.rebuild_index();
    ASSERT_GT(book.size(), 300u);
    SearchStats stats;
    const Vectors queries = btf_like(200, layout, 27);
    for (const auto& v : queries) book.find(v, t, &stats);
    // Measured 38 % and 8.7 %; without the index every signature is bounded (100 %), without the
    // filter every bounded candidate is compared.
    EXPECT_LT(double(stats.bounded), 0.6 * double(stats.codebook))
        << stats.bounded << " of " << stats.codebook;
    EXPECT_LT(double(stats.compared), 0.15 * double(stats.codebook))
        << stats.compared << " of " << stats.codebook;
    expect_same_as_brute_force(book, Vectors(queries.begin(), queries.begin() + 50), t);
}

// ---- mssim -----------------------------------------------------------------------------------

// SSIM by its definition, window by window (no separable filtering, no streaming): the local
// statistics of x and y = scale·c over the truncated, renormalized Gaussian window of each value.
double reference_mssim(const std::vector<float>& x, const std::vector<float>& c, double scale,
                       const Layout& layout, const SsimOptions& s, bool luminance) {
    const uint32_t na = layout.dims.size() > 1 ? layout.dims[0] : 1;
    const uint32_t nb = layout.dims.back();
    const int r = int(s.radius);
    const double c1 = std::pow(s.k1 * s.dynamic_range, 2), c2 = std::pow(s.k2 * s.dynamic_range, 2);
    std::vector<double> dis;
    for (uint32_t ch = 0; ch < layout.channels; ++ch) {
        const double sc = luminance && ch == 0 ? scale : 1;
        const size_t off = ch * layout.channel_size();
        for (int a = 0; a < int(na); ++a)
            for (int b = 0; b < int(nb); ++b) {
                double wsum = 0, mx = 0, my = 0, xx = 0, yy = 0, xy = 0;
                for (int i = std::max(0, a - r); i <= std::min(int(na) - 1, a + r); ++i)
                    for (int j = std::max(0, b - r); j <= std::min(int(nb) - 1, b + r); ++j) {
                        const double w = std::exp(-double((i - a) * (i - a) + (j - b) * (j - b)) /
                                                  (2 * s.sigma * s.sigma));
                        const double xv = x[off + i * nb + j], yv = sc * c[off + i * nb + j];
                        wsum += w, mx += w * xv, my += w * yv;
                        xx += w * xv * xv, yy += w * yv * yv, xy += w * xv * yv;
                    }
                mx /= wsum, my /= wsum, xx /= wsum, yy /= wsum, xy /= wsum;
                const double ssim = (2 * mx * my + c1) * (2 * (xy - mx * my) + c2) /
                                    ((mx * mx + my * my + c1) * (xx - mx * mx + yy - my * my + c2));
                dis.push_back(1 - ssim);
            }
    }
    const size_t k = size_t(std::floor((100 - s.percentile) / 100 * double(dis.size()) + 1e-9));
    std::sort(dis.begin(), dis.end());
    return dis[dis.size() - 1 - k];
}

TEST(MlvqVq, MssimIsThePercentileOfLocalSsimOverTheWindow) {
    for (const Layout& layout : {Layout{{11}, 1}, Layout{{5, 7}, 1}, Layout{{11, 11}, 3}}) {
        for (Kind kind : {Kind::luminance, Kind::chromaticity}) {
            auto o = options(layout.dims, kind, Measure::mssim, kInf, layout.channels);
            o.ssim.radius = layout.dims.size() > 1 ? 2 : 5;
            o.ssim.percentile = 90;
            Codebook book(o);
            const Vectors data = btf_like(5, layout, 16);
            book.add(data[0]);
            for (size_t i = 1; i < data.size(); ++i) {
                const Match m = book.find(data[i]);
                ASSERT_TRUE(m);
                const double ref =
                    reference_mssim(data[i], {book.vector(0).begin(), book.vector(0).end()},
                                    m.scale, layout, o.ssim, kind == Kind::luminance);
                EXPECT_NEAR(m.error, ref, 1e-6) << "vector " << i;
            }
        }
    }
}

TEST(MlvqVq, MssimAllowsExactlyThePercentilesOutliers) {
    // One-value windows (radius 0): the SSIM of a value is its luminance term alone, so a changed
    // value is one outlier. 121 values at the 98th percentile allow ⌊0.02 · 121⌋ = 2.
    auto o = options({11, 11}, Kind::chromaticity, Measure::mssim, 1e-9);
    o.ssim.radius = 0;
    Codebook book(o);
    const std::vector<float> base = uniform_vectors(1, 121, 17, 0.2f, 0.8f)[0];
    book.add(base);
    std::vector<float> q = base;
    q[3] += 0.3f;
    q[77] -= 0.1f;
    EXPECT_TRUE(book.find(q));
    q[100] += 0.2f;
    EXPECT_FALSE(book.find(q));
    EXPECT_FALSE(book.find_brute_force(q, 1e-9));
    // Measured: the third largest of 1 − l over the three changed values.
    const Match m = book.find(q, kInf);
    std::vector<double> d;
    for (int i : {3, 77, 100}) {
        const double x = q[i], y = base[i], c1 = 1e-4;
        d.push_back(1 - (2 * x * y + c1) / (x * x + y * y + c1));
    }
    EXPECT_NEAR(m.error, *std::min_element(d.begin(), d.end()), 1e-12);
}

TEST(MlvqVq, MssimIndexFindsMatchesOnTheEdgeOfItsRadius) {
    // One-value windows, so 1 − SSIM = 1 − l per value. A scaled copy b = (1 ± ε)·a of the query
    // makes every inequality behind the radius of the index over the means tight (each value at
    // the same 1 − l, ‖b‖ = ‖a‖ + ‖a − b‖), and so do outliers as large as the code-book's
    // largest mean. The threshold is set to the planted candidate's own measure: a radius any
    // smaller, or a box bound any larger, would lose it.
    for (uint32_t length : {11u, 121u}) {
        auto o = options({length}, Kind::chromaticity, Measure::mssim, 0);
        o.ssim.radius = 0;
        o.ssim.dynamic_range = 1e-3;
        for (double eps : {-0.3, -0.05, 0.05, 0.2, 0.6}) {
            Vectors entries = uniform_vectors(100, length, 30, 4.0f, 5.0f);
            const std::vector<float> q = uniform_vectors(1, length, 31, 0.5f, 1.0f)[0];
            std::vector<float> planted = q;
            for (float& x : planted) x = float(x * (1 + eps));
            if (length == 121) planted[7] = planted[90] = 5.0f;  // the k = 2 outliers
            entries[70] = planted;
            const Codebook book = filled(o, entries);
            const double t = book.find_brute_force(q, kInf).error;
            ASSERT_EQ(book.find_brute_force(q, kInf).index, 70u);
            const Match m = book.find(q, t);
            EXPECT_EQ(m.index, 70u) << "length " << length << " eps " << eps;
            EXPECT_EQ(m.error, t);
        }
    }
}

TEST(MlvqVq, MssimSearchEqualsBruteForce) {
    struct Case {
        Layout layout;
        Kind kind;
    };
    for (const Case& c :
         {Case{{{11}, 1}, Kind::luminance}, Case{{{11, 11}, 1}, Kind::luminance},
          Case{{{11}, 2}, Kind::chromaticity}, Case{{{7, 5}, 3}, Kind::luminance}}) {
        auto o = options(c.layout.dims, c.kind, Measure::mssim, 0, c.layout.channels);
        const Codebook book = filled(o, btf_like(300, c.layout, 18));
        const Vectors queries = btf_like(60, c.layout, 19);
        for (double t : {0.0, 0.01, 0.05, 0.2, kInf}) expect_same_as_brute_force(book, queries, t);
        const Codebook random = filled(o, uniform_vectors(200, c.layout.size(), 20, 0, 1));
        expect_same_as_brute_force(random, uniform_vectors(40, c.layout.size(), 21), 0.3);
        expect_same_as_brute_force(random, uniform_vectors(40, c.layout.size(), 21), kInf);
    }
    expect_same_growth(options({11}, Kind::luminance, Measure::mssim, 0.02),
                       btf_like(1500, Layout{{11}, 1}, 22));
}

TEST(MlvqVq, MssimThresholdBoundsTheReconstructionsPercentile) {
    const Layout layout{{11, 11}, 1};
    auto o = options(layout.dims, Kind::luminance, Measure::mssim, 0.05);
    Codebook book(o);
    for (const auto& v : btf_like(400, layout, 23)) {
        const Match m = book.find_or_add(v);
        const auto c = book.vector(m.index);
        const double ref = reference_mssim(v, {c.begin(), c.end()}, m.scale, layout, o.ssim, true);
        EXPECT_LE(ref, 0.05 + 1e-6);
        EXPECT_NEAR(ref, m.error, 1e-6);
    }
    EXPECT_LT(book.size(), 200u);
}

// ---- batches ---------------------------------------------------------------------------------

TEST(MlvqVq, BatchEqualsSingleQueriesForAnyThreadCount) {
    for (Measure measure : {Measure::mse, Measure::mssim}) {
        const Layout layout{{11}, 1};
        const double t = measure == Measure::mse ? 2e-4 : 0.02;
        Codebook book(options(layout.dims, Kind::luminance, measure, t));
        for (const auto& v : btf_like(3000, layout, 24)) book.find_or_add(v);
        const Vectors queries = btf_like(1000, layout, 25);
        std::vector<float> flat;
        for (const auto& v : queries) flat.insert(flat.end(), v.begin(), v.end());
        std::vector<Match> one, all;
        {
            ThreadLimit limit(1);
            one = book.find_batch(flat);
        }
        all = book.find_batch(flat);
        ASSERT_EQ(one.size(), queries.size());
        ASSERT_EQ(all.size(), queries.size());
        for (size_t i = 0; i < queries.size(); ++i) {
            const Match m = book.find(queries[i]);
            EXPECT_EQ(one[i].index, m.index);
            EXPECT_EQ(all[i].index, m.index);
            EXPECT_EQ(all[i].error, m.error);
            EXPECT_EQ(all[i].scale, m.scale);
        }
    }
}

}  // namespace
}  // namespace btf::mlvq
