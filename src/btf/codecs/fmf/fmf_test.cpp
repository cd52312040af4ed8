// SPDX-License-Identifier: MIT
#include "btf/codecs/fmf/fmf.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "btf/codecs/factor/coded.h"
#include "btf/codecs/factor/model.h"
#include "btf/core/color.h"
#include "btf/io/function_source.h"
#include "btf/io/package.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

using factor::FactorMaterial;

// A smooth, spatially varying, colourful BTF with a highlight: rank grows with the sampling.
Rgb value_of(const Sampling& s, int view, int light, int x, int y) {
    const Vec3 wo = s.views.vector(view), wi = s.lights.vector(light);
    const double fx = std::sin(0.7 * x + 0.3 * y), fy = std::cos(0.4 * y - 0.2 * x);
    const Vec3 h = {wi.x + wo.x, wi.y + wo.y, wi.z + wo.z};
    const double hn = std::sqrt(h.x * h.x + h.y * h.y + h.z * h.z);
    const double spec = std::pow(std::max(0.0, h.z / hn), 20.0 + 10 * fy);
    const double diffuse = wi.z * (0.6 + 0.3 * fx);
    return {float(diffuse * 0.8 + spec * 0.5), float(diffuse * (0.5 + 0.2 * fy) + spec * 0.5),
            float(diffuse * 0.3 + spec * (0.4 + 0.1 * fx))};
}

Sampling small_sampling(int views, int lights) {
    std::vector<int> vi, li;
    for (int i = 0; i < views; ++i) vi.push_back(i * 81 / views);
    for (int i = 0; i < lights; ++i) li.push_back(i * 81 / lights);
    return {DirectionSet::ubo81().subset(vi, "views"), DirectionSet::ubo81().subset(li, "lights")};
}

FunctionSource small_source(int size = 10, int views = 9, int lights = 12) {
    const Sampling s = small_sampling(views, lights);
    return FunctionSource(s, size, size - 2,
                          [s](int v, int l, int x, int y) { return value_of(s, v, l, x, y); });
}

Package encode(const BtfSource& source, Params params) {
    return fmf_codec().encode(source, params);
}

// f(source value, material value) at every texel of every image.
template <class F>
void for_each_sample(const BtfSource& source, const Material& material, F&& f) {
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); ++l) {
            const Image image = source.image(v, l);
            for (int y = 0; y < source.height(); ++y)
                for (int x = 0; x < source.width(); ++x)
                    f(image.rgb(x, y), material.eval_sample(x, y, v, l));
        }
}

double rmse(const BtfSource& source, const Material& material) {
    double sum = 0;
    int64_t n = 0;
    for_each_sample(source, material, [&](const Rgb& a, const Rgb& b) {
        sum += (a.r - b.r) * (a.r - b.r) + (a.g - b.g) * (a.g - b.g) + (a.b - b.b) * (a.b - b.b);
        n += 3;
    });
    return std::sqrt(sum / n);
}

// Mean CIEDE2000 over every sample.
double mean_de2000(const BtfSource& source, const Material& material) {
    double sum = 0;
    int64_t n = 0;
    for_each_sample(source, material, [&](const Rgb& a, const Rgb& b) {
        sum += ciede2000(rgb_to_lab(a), rgb_to_lab(b));
        ++n;
    });
    return sum / double(n);
}

Uv texel_centre(const Material& m, int x, int y) {
    return {(x + 0.5) / m.width(), (y + 0.5) / m.height()};
}

TEST(Fmf, FullRankReconstructsTheSourceInEveryColourMode) {
    const FunctionSource source = small_source();
    for (const std::string colour : {"rgb", "decorrelated", "per-channel", "model11"}) {
        for (const std::string mean : {"false", "true"}) {
            const Package p = encode(source, Params({{"components", "400"},
                                                     {"colour", colour},
                                                     {"mean", mean},
                                                     {"quantize", "f32"}}));
            const auto material = fmf_codec().open(p);
            EXPECT_LT(rmse(source, *material), 2e-5) << colour << " mean=" << mean;
        }
    }
}

TEST(Fmf, LogModeReconstructsHdrValues) {
    const Sampling s = small_sampling(4, 6);
    const FunctionSource source(s, 6, 6, [s](int v, int l, int x, int y) {
        const Rgb c = value_of(s, v, l, x, y);
        return Rgb{c.r * 40, c.g * 40, c.b * 40};  // up to ~40: HDR
    });
    const Package p = encode(source, Params({{"components", "400"},
                                             {"log", "true"},
                                             {"colour", "decorrelated"},
                                             {"quantize", "f32"}}));
    EXPECT_LT(rmse(source, *fmf_codec().open(p)), 1e-3);
}

TEST(Fmf, ValuesAtSampleDirectionsEqualTheDecodedMatrix) {
    const FunctionSource source = small_source();
    const auto material =
        fmf_codec().open(encode(source, Params({{"components", "12"}, {"mean", "true"}})));
    const Sampling& s = source.sampling();
    for (int v = 0; v < s.num_views(); v += 2)
        for (int l = 0; l < s.num_lights(); l += 3)
            for (int y = 0; y < source.height(); y += 3)
                for (int x = 0; x < source.width(); x += 2) {
                    const Rgb a = material->eval(texel_centre(*material, x, y), s.lights.vector(l),
                                                 s.views.vector(v));
                    const Rgb b = material->eval_sample(x, y, v, l);
                    EXPECT_NEAR(a.r, b.r, 1e-5);
                    EXPECT_NEAR(a.g, b.g, 1e-5);
                    EXPECT_NEAR(a.b, b.b, 1e-5);
                }
}

std::vector<Query> random_queries(int count, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u01(0, 1);
    auto direction = [&] {
        const double z = u01(rng), phi = 2 * M_PI * u01(rng), r = std::sqrt(1 - z * z);
        return Vec3{r * std::cos(phi), r * std::sin(phi), z};
    };
    std::vector<Query> q(count);
    for (Query& x : q) x = {{3 * u01(rng) - 1, 3 * u01(rng) - 1}, direction(), direction()};
    return q;
}

TEST(Fmf, VectorizedEvaluationMatchesTheScalarReference) {
    const FunctionSource source = small_source();
    for (const std::string colour : {"rgb", "decorrelated"}) {
        const auto material = fmf_codec().open(
            encode(source, Params({{"components", "13"}, {"mean", "true"}, {"colour", colour}})));
        const auto& fm = dynamic_cast<const FactorMaterial&>(*material);
        const auto queries = random_queries(2000, 11);
        std::vector<Rgb> batch(queries.size());
        fm.eval_batch(queries, batch);
        for (size_t i = 0; i < queries.size(); ++i) {
            const Query& q = queries[i];
            const Rgb fast = fm.eval(q.uv, q.wi, q.wo), ref = fm.eval_reference(q.uv, q.wi, q.wo);
            ASSERT_NEAR(fast.r, ref.r, 2e-5) << colour << " query " << i;
            ASSERT_NEAR(fast.g, ref.g, 2e-5);
            ASSERT_NEAR(fast.b, ref.b, 2e-5);
            ASSERT_EQ(fast, batch[i]);
        }
    }
}

TEST(Fmf, BatchedCoherentQueriesReuseDirectionsCorrectly) {
    const FunctionSource source = small_source();
    const auto material = fmf_codec().open(encode(source, Params({{"components", "8"}})));
    auto queries = random_queries(300, 5);
    for (size_t i = 0; i < queries.size(); ++i) {  // runs of equal directions
        queries[i].wi = queries[i / 50 * 50].wi;
        queries[i].wo = queries[i / 50 * 50].wo;
    }
    std::vector<Rgb> batch(queries.size());
    material->eval_batch(queries, batch);
    for (size_t i = 0; i < queries.size(); ++i)
        EXPECT_EQ(batch[i], material->eval(queries[i].uv, queries[i].wi, queries[i].wo));
}

TEST(Fmf, PrefixesDecodeWithMonotonicallyDecreasingError) {
    const FunctionSource source = small_source();
    for (const std::string colour : {"rgb", "decorrelated"}) {
        const Package full = encode(
            source,
            Params(
                {{"components", "16"}, {"colour", colour}, {"mean", "true"}, {"quantize", "f32"}}));
        // The source has rank ≤ 16: the last prefixes reproduce it to float rounding (RMSE
        // ~3e-7), where another component only changes how the sums round (a build of the
        // `package` preset measured 2.74720e-7, then 2.74776e-7 with the last section).
        constexpr double kRounding = 1e-6;
        double previous = INFINITY;
        int components = -1;
        for (int n = 0; n <= full.declared_sections; ++n) {
            Package prefix = full;
            prefix.sections.resize(n);
            const auto material = fmf_codec().open(prefix);
            const int k = dynamic_cast<const FactorMaterial&>(*material).total_components();
            const double e = rmse(source, *material);
            if (k > components && components >= 0 && previous > kRounding) {
                EXPECT_LT(e, previous) << colour << " " << n;
            }
            EXPECT_LE(e, std::max(previous, kRounding)) << colour << " " << n;
            previous = e;
            components = k;
        }
        EXPECT_EQ(components, 16);
    }
}

// Coded storage keeps the order: a component's section never makes the error larger (one whose
// quantization would cost more than it adds is stored as zeros), at the default quality and at
// a coarse one, and the components that survive bring the error near the unquantized one.
TEST(Fmf, CodedPrefixesDecodeWithMonotonicallyDecreasingError) {
    const FunctionSource source = small_source(16);
    const double exact = rmse(
        source,
        *fmf_codec().open(encode(source, Params({{"components", "12"}, {"quantize", "f32"}}))));
    for (const std::string quality : {"50", "30"}) {
        const Package full = encode(
            source, Params({{"components", "12"}, {"quantize", "coded"}, {"quality", quality}}));
        std::vector<double> errors;
        for (int n = 2; n <= full.declared_sections; ++n) {  // after tables and means
            Package prefix = full;
            prefix.sections.resize(n);
            errors.push_back(rmse(source, *fmf_codec().open(prefix)));
            if (errors.size() > 1) {
                EXPECT_LE(errors.back(), errors[errors.size() - 2])
                    << "quality " << quality << ", " << n << " sections";
            }
        }
        EXPECT_LT(errors[3], 0.5 * errors[0]) << quality;
        // Decoded to half floats: the evaluator keeps half rows, as for f16 packages.
        EXPECT_TRUE(dynamic_cast<const FactorMaterial&>(*fmf_codec().open(full)).half_rows());
        // Each component adds at most about Δ²/6 to the mean squared error (Δ²/12 from each
        // factor), and the source has rank 5.
        const double step = full.header.at("model").at("coding").at("step").get<double>();
        EXPECT_LT(errors.back(), exact + std::sqrt(5.0 / 6.0) * step) << quality;
    }
}

TEST(Fmf, DecorrelatedColourAllocatesComponentsByEnergy) {
    const Sampling s = small_sampling(6, 8);
    const FunctionSource grey(s, 8, 8, [s](int v, int l, int x, int y) {
        const float g = value_of(s, v, l, x, y).g;
        return Rgb{g, g, g};
    });
    const factor::Model m = fmf::factorize(
        grey, fmf::parse_options(Params({{"components", "6"}, {"colour", "decorrelated"}})));
    ASSERT_EQ(m.blocks.size(), 3u);
    EXPECT_EQ(m.blocks[0].components(), 6);  // a grey BTF has no chroma
    EXPECT_EQ(m.blocks[1].components() + m.blocks[2].components(), 0);
}

// Largest error of the quantized factors, per sample: Σ_k |a||Δb| + |b||Δa| + |Δa||Δb| with the
// per-value bounds of the storage (f16: relative 2⁻¹¹; u8: half a step of the column's range;
// coded: half of a's step, and for the DCT-coded b factor/coded.h's kImageErrorPerStep steps,
// the steps as each component section states them).
TEST(Fmf, QuantizedDecodingStaysWithinTheDocumentedBounds) {
    const FunctionSource source = small_source();
    const Params base({{"components", "10"}, {"quantize", "f32"}});
    const auto exact = fmf_codec().open(encode(source, base));
    const factor::Model& model = dynamic_cast<const FactorMaterial&>(*exact).model();
    const factor::Block& block = model.blocks[0];
    for (const std::string q : {"f16", "u8", "coded"}) {
        Params params = base;
        params.set("quantize", q);
        if (q == "coded") params.set("quality", "25");
        const Package package = encode(source, params);
        const auto material = fmf_codec().open(package);
        std::vector<float> da(block.components()), db(block.components());
        for (int k = 0; k < block.components(); ++k) {
            if (q == "u8") {
                da[k] = (block.a.col(k).maxCoeff() - block.a.col(k).minCoeff()) / 255 / 2 * 1.001f;
                db[k] = (block.b.col(k).maxCoeff() - block.b.col(k).minCoeff()) / 255 / 2 * 1.001f;
            }
            if (q == "coded") {
                float steps[2];
                const PackageSection* s = package.find(fmt::format("b0.k{}", k));
                ASSERT_NE(s, nullptr);
                ASSERT_EQ(s->data[2], 1) << "the 10 × 10 texels are DCT-coded as an image";
                std::memcpy(steps, s->data.data() + 4, 8);
                // Plus the rounding of the decoded values to halves. a rounded (s_a / 2), or
                // as DCT-coded images of its planes (prediction 129): each plane off by
                // kImageErrorPerStep steps, an outer channel by its offset's and the middle's.
                const float a_error = s->data[1] == 129
                                          ? 2 * float(factor::coded::kImageErrorPerStep) * steps[0]
                                          : steps[0] / 2;
                da[k] = a_error * 1.001f + std::ldexp(block.a.col(k).cwiseAbs().maxCoeff(), -10);
                db[k] = float(factor::coded::kImageErrorPerStep) * steps[1] * 1.001f +
                        std::ldexp(block.b.col(k).cwiseAbs().maxCoeff(), -10);
            }
        }
        double worst_ratio = 0;
        for (int v = 0; v < source.num_views(); ++v)
            for (int l = 0; l < source.num_lights(); ++l)
                for (int t = 0; t < source.width() * source.height(); ++t) {
                    const int x = t % source.width(), y = t / source.width();
                    const Rgb e = exact->eval_sample(x, y, v, l);
                    const Rgb d = material->eval_sample(x, y, v, l);
                    const float diff[3] = {d.r - e.r, d.g - e.g, d.b - e.b};
                    for (int c = 0; c < 3; ++c) {
                        const int64_t row = (int64_t(v) * source.num_lights() + l) * 3 + c;
                        double bound = 1e-6;
                        for (int k = 0; k < block.components(); ++k) {
                            const double a = std::abs(block.a(row, k)), b = std::abs(block.b(t, k));
                            const double ea = q == "f16" ? a * std::ldexp(1.0, -11) : da[k];
                            const double eb = q == "f16" ? b * std::ldexp(1.0, -11) : db[k];
                            // The decoded factors are those of the same SVD (the encoding is
                            // deterministic), so the bound holds sample by sample.
                            bound += a * eb + b * ea + ea * eb;
                        }
                        ASSERT_LE(std::abs(diff[c]), bound) << q;
                        worst_ratio = std::max(worst_ratio, std::abs(diff[c]) / bound);
                    }
                }
        EXPECT_GT(worst_ratio, 0.0) << q << ": quantization changed nothing";
    }
}

TEST(Fmf, PackageRoundTripThroughBytes) {
    const FunctionSource source = small_source();
    Package p = encode(source, Params({{"components", "7"}, {"quantize", "u8"}}));
    const auto direct = fmf_codec().open(p);
    const std::vector<uint8_t> bytes = encode_package(p);
    const Package back = decode_package(bytes, "memory");
    EXPECT_TRUE(back.complete());
    const auto material = open_material(back);
    for (int v = 0; v < source.num_views(); ++v)
        EXPECT_EQ(material->eval_sample(3, 4, v, v % source.num_lights()),
                  direct->eval_sample(3, 4, v, v % source.num_lights()));
    EXPECT_EQ(back.header.at("params").at("quantize"), "u8");
    EXPECT_EQ(back.header.at("raw_bytes_8bit"), 10 * 8 * 9 * 12 * 3);
}

TEST(Fmf, PackagesAreTheSameBytesForAnyThreadCount) {
    // 4096 texels (two 2048-column slices of the transposed products) and 150 rows per view
    // (two 128-row chunks of the direct products), for both SVD methods.
    const FunctionSource source = small_source(64, 9, 50);
    for (const std::string svd : {"krylov", "subspace"}) {
        const Params params({{"components", "9"}, {"svd", svd}});
        const auto bytes = test::bytes_per_thread_count([&] {
            Package p = encode(source, params);
            return encode_package(p);
        });
        EXPECT_EQ(bytes[0], bytes[1]) << svd;
        EXPECT_EQ(bytes[0], bytes[2]) << svd;
    }
}

// --target-size: with coded storage the package lands within 5 % under the target; the choice
// keeps more components or a higher quality for a larger target, and lowers the error; the mean
// CIEDE2000 it reports (on its sample: 128 of the 960 texels of each image) is within 10 % of
// the mean over every sample; a target below one component's size is refused.
TEST(Fmf, EncodesToATargetSize) {
    const FunctionSource source = small_source(32);
    const auto& codec = dynamic_cast<const factor::FactorCodec&>(fmf_codec());
    const Params params({{"components", "12"}, {"quantize", "coded"}});
    // The smallest package (one component at quality 0: the tables and header dominate) and the
    // whole one at the default quality; targets between them.
    Package smallest =
        encode(source, Params({{"components", "1"}, {"quantize", "coded"}, {"quality", "0"}}));
    Package whole = encode(source, params);
    const double low = double(encode_package(smallest).size()),
                 high = double(encode_package(whole).size());
    double previous_error = INFINITY;
    for (const uint64_t target :
         {uint64_t(low + 0.3 * (high - low)), uint64_t(low + 0.8 * (high - low))}) {
        factor::FactorCodec::SizeChoice choice;
        Progress quiet;
        Package p = codec.encode_to_size(source, params, target, {}, quiet, &choice);
        const std::vector<uint8_t> bytes = encode_package(p);
        EXPECT_LE(bytes.size(), target);
        EXPECT_GE(double(bytes.size()), 0.95 * double(target));
        EXPECT_EQ(choice.bytes, bytes.size());
        EXPECT_EQ(p.header.at("params").at("quality"), choice.quality);
        const double e = mean_de2000(source, *fmf_codec().open(p));
        EXPECT_LT(e, previous_error) << target;
        EXPECT_NEAR(choice.de2000, e, 0.1 * e) << target;
        previous_error = e;
    }
    Progress quiet;
    const uint64_t tiny = uint64_t(low / 2);
    EXPECT_EQ(test::error_of([&] { codec.encode_to_size(source, params, tiny, {}, quiet); }),
              fmt::format("--target-size {}: even one component at quality 0 takes more", tiny));
}

TEST(Fmf, RejectsBadParameters) {
    const FunctionSource source = small_source();
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"componets", "3"}}));
              }),
              "codec fmf: unknown parameter 'componets' (known: components, colour, log, log-eps, "
              "mean, quantize, svd, oversampling, power-iterations, block, seed, quality)");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"components", "0"}}));
              }),
              "parameter components: 0 is outside [1, 4096]");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"colour", "cmyk"}}));
              }),
              "parameter colour: 'cmyk' is not one of rgb, decorrelated, per-channel, model11");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"quantize", "u4"}}));
              }),
              "parameter quantize: 'u4' is not one of f32, f16, u8, coded");
}

// Private writable memory the process has mapped (VmData), in bytes.
int64_t data_bytes() {
    std::ifstream status("/proc/self/status");
    std::string line;
    while (std::getline(status, line))
        if (line.rfind("VmData:", 0) == 0) return std::stoll(line.substr(7)) * 1024;
    return -1;
}

// The streaming claim: a BTF whose raw float32 data (1.3 GB) is several times the memory the
// process may add still compresses. The child process caps its data segment and private
// mappings (RLIMIT_DATA) at what it has mapped already (libraries' data, about 240 MB) plus
// 384 MB, shows that the cap is real by failing to allocate the raw size, then factorizes.
TEST(Fmf, CompressesABtfLargerThanItsMemoryCap) {
#if BTF_TEST_ASAN
    // The normal build runs it: AddressSanitizer's allocator reports running out of memory
    // under the cap instead of throwing std::bad_alloc (make test-sanitize).
    GTEST_SKIP() << "a data-size cap and AddressSanitizer exclude each other";
#endif
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        constexpr int64_t kHeadroom = 384ll << 20;
        const int64_t base = data_bytes();
        if (base < 0) _exit(10);
        const rlim_t cap = static_cast<rlim_t>(base + kHeadroom);
        const rlimit limit{cap, cap};
        if (setrlimit(RLIMIT_DATA, &limit) != 0) _exit(10);
        // A rank-3 BTF from cheap terms, so that reading it costs little next to the passes.
        const Sampling s{DirectionSet::ubo81(), DirectionSet::ubo81()};
        auto value = [&s](int v, int l, int x, int y) {
            const Vec3 wi = s.lights.vector(l), wo = s.views.vector(v);
            const double sum = wi.z * (0.5 + 0.003 * x) + wi.z * wo.z * (0.2 + 0.001 * y) +
                               0.3 * std::max(0.0, wi.x * wo.x);
            return Rgb{float(sum), float(0.8 * sum), float(0.5 * sum)};
        };
        const FunctionSource source(s, 128, 128, value);
        if (source.raw_bytes() < 3 * kHeadroom) _exit(11);
        try {
            std::vector<float> whole(source.raw_bytes() / 4);
            _exit(12);  // the cap did not hold
        } catch (const std::bad_alloc&) {
        }
        try {
            const Package p =
                encode(source, Params({{"components", "4"}, {"power-iterations", "0"}}));
            const auto material = fmf_codec().open(p);
            const Rgb a = material->eval_sample(5, 7, 40, 20), b = value(40, 20, 5, 7);
            _exit(std::abs(a.g - b.g) < 1e-3 * std::abs(b.g) + 1e-5 ? 0 : 13);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "child: %s\n", e.what());
            _exit(14);
        }
    }
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0)
        << "10: setrlimit failed, 11: source too small, 12: cap not effective, 13: wrong value, "
           "14: factorization failed";
}

}  // namespace
}  // namespace btf
