// SPDX-License-Identifier: MIT
// `btf compress` and `btf compress-many` across MPI ranks (docs/distributed.md), started by the
// real launcher with more ranks than this machine has cores (mpirun --oversubscribe).

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/SVD>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/material_source.h"
#include "btf/core/image.h"
#include "btf/io/open.h"
#include "btf/testing/cli.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using testing::HasSubstr;
using testing::Not;

// `mpirun -np N btf --quiet ARGS`, under a time limit so that a hang fails instead of waiting.
test::CliResult launch(int ranks, const std::string& args) {
    const std::string root = ::geteuid() == 0 ? " --allow-run-as-root" : "";
    return test::run_shell(fmt::format("timeout 300 {}{} --oversubscribe -np {} {} --quiet {}",
                                       BTF_MPIEXEC, root, ranks, BTF_TOOL_PATH, args));
}

class Mpi : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        if (std::string(BTF_MPIEXEC).empty()) return;
        s_dir = std::make_unique<test::TempFolder>("btf_mpi");
        // A small material with 81 views: 27 for each of 3 ranks.
        ASSERT_EQ(test::run("synth --preset leather --size 24 -o " + at("m.h5")).code, 0);
    }
    static void TearDownTestSuite() { s_dir.reset(); }
    void SetUp() override {
        if (std::string(BTF_MPIEXEC).empty())
            GTEST_SKIP() << "btf was built without MPI (libopenmpi-dev missing)";
    }
    static std::string at(const std::string& name) { return (s_dir->path() / name).string(); }
    static std::unique_ptr<test::TempFolder> s_dir;
};
std::unique_ptr<test::TempFolder> Mpi::s_dir;

// Every decoded value of a package, image by image.
std::vector<float> decoded(const std::string& package) {
    const auto source = open_package_source(package);
    std::vector<float> out;
    Image image;
    for (int v = 0; v < source->num_views(); ++v)
        for (int l = 0; l < source->num_lights(); ++l) {
            source->read_image(v, l, image);
            out.insert(out.end(), image.data(), image.data() + image.num_pixels() * 3);
        }
    return out;
}

double relative_rms(const std::vector<float>& a, const std::vector<float>& b) {
    EXPECT_EQ(a.size(), b.size());
    double d = 0, n = 0;
    for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
        d += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
        n += double(b[i]) * b[i];
    }
    return std::sqrt(d / n);
}

std::string read_bytes(const std::string& path) {
    return test::read_file(path);
}

TEST_F(Mpi, RanksAgreeWithOneProcessAndRepeatTheirBits) {
    const std::string options = " --codec fmf -p components=8 -p quantize=f32 --no-error -o ";
    ASSERT_EQ(test::run("compress " + at("m.h5") + options + at("one.btfpkg")).code, 0);
    const std::vector<float> one = decoded(at("one.btfpkg"));
    for (int ranks : {1, 2, 3}) {
        const std::string a = at(fmt::format("r{}a.btfpkg", ranks)),
                          b = at(fmt::format("r{}b.btfpkg", ranks));
        test::CliResult r = launch(ranks, "compress " + at("m.h5") + options + a);
        ASSERT_EQ(r.code, 0) << r.output;
        if (ranks > 1) EXPECT_THAT(r.output, HasSubstr(fmt::format("on {} MPI ranks", ranks)));
        r = launch(ranks, "compress " + at("m.h5") + options + b);
        ASSERT_EQ(r.code, 0) << r.output;
        // Bitwise the same for as many ranks; one rank is one process.
        EXPECT_EQ(read_bytes(a), read_bytes(b)) << ranks << " ranks";
        if (ranks == 1) EXPECT_EQ(read_bytes(a), read_bytes(at("one.btfpkg")));
        const double difference = relative_rms(decoded(a), one);
        EXPECT_LE(difference, 1e-5) << ranks << " ranks";
        if (ranks > 1) EXPECT_GT(difference, 0) << "the ranks' partial sums add in another order";
    }
}

TEST_F(Mpi, EveryFactorizationCodecDistributes) {
    // The default storage of each (f16 factors, or u8/f16 for perceptual's levels): a factor
    // value that differs in its 7th digit may round to the next f16, 2⁻¹¹ of it, so the bound is
    // looser than the arithmetic's 1e-5 (above).
    for (const std::string codec : {"fmf", "pca-views", "lpca", "perceptual"}) {
        const std::string params = " --codec " + codec + " -p components=6 --no-error -o ";
        const std::string one = at(codec + "-one.btfpkg"), three = at(codec + "-three.btfpkg");
        ASSERT_EQ(test::run("compress " + at("m.h5") + params + one).code, 0) << codec;
        const test::CliResult r = launch(3, "compress " + at("m.h5") + params + three);
        ASSERT_EQ(r.code, 0) << codec << ": " << r.output;
        EXPECT_LE(relative_rms(decoded(three), decoded(one)), 2e-4) << codec;
    }
}

TEST_F(Mpi, StaysWithinOnePercentOfTheEckartYoungOptimum) {
    // The BTF as one matrix (rows: image × channel, columns: texels; row order does not change
    // singular values), its exact singular values, and the optimum of rank C.
    const auto source = open_source(at("m.h5"));
    const int images = source->sampling().num_images(), texels = int(source->num_texels());
    Eigen::MatrixXd m(int64_t(images) * 3, texels);
    Image image;
    for (int i = 0; i < images; ++i) {
        source->read_image(i / source->num_lights(), i % source->num_lights(), image);
        for (int t = 0; t < texels; ++t)
            for (int c = 0; c < 3; ++c) m(int64_t(i) * 3 + c, t) = image.data()[int64_t(t) * 3 + c];
    }
    const Eigen::VectorXd sigma = Eigen::BDCSVD<Eigen::MatrixXd>(m).singularValues();
    const int components = 6;
    const double total = m.squaredNorm(), rms = std::sqrt(total / double(m.size()));
    const double optimum = std::sqrt((total - sigma.head(components).squaredNorm()) / total);
    for (int ranks : {2, 3}) {
        const std::string pkg = at(fmt::format("ey{}.btfpkg", ranks));
        const test::CliResult r =
            launch(ranks, fmt::format("compress {} --codec fmf -p colour=rgb -p components={} "
                                      "-p quantize=f32 --no-error -o {}",
                                      at("m.h5"), components, pkg));
        ASSERT_EQ(r.code, 0) << r.output;
        const double error = sample_rmse(*source, *open_material(fs::path(pkg))) / rms;
        EXPECT_LE(error, 1.01 * optimum) << ranks << " ranks";
        EXPECT_GE(error, optimum * (1 - 1e-6)) << "no rank-" << components << " beats Eckart–Young";
    }
}

TEST_F(Mpi, AFailingRankStopsEveryRankAndLeavesNoOutput) {
    // An image set whose images are read view by view; one image of a view of the last rank
    // (views 54–80 of 81) cut short: its header reads (opening checks every header), its pixels
    // do not.
    const std::string set = at("set");
    ASSERT_EQ(test::run("convert " + at("m.h5") + " " + set + " --format png").code, 0);
    fs::path broken;
    for (const auto& entry : fs::directory_iterator(set))
        if (entry.path().filename().string().find("tv075_pv300") != std::string::npos)
            broken = entry.path();
    ASSERT_FALSE(broken.empty());
    fs::resize_file(broken, fs::file_size(broken) / 2);
    const std::string out = at("failed.btfpkg");
    const test::CliResult r =
        launch(3, "compress " + set + " --codec fmf -p components=4 --no-error -o " + out);
    EXPECT_NE(r.code, 0);
    // Every rank reports rank 2's failure, naming the file.
    const std::string line = "btf: error: rank 2 of 3: " + broken.string();
    size_t count = 0;
    for (size_t at = r.output.find(line); at != std::string::npos; at = r.output.find(line, at + 1))
        ++count;
    EXPECT_EQ(count, 3u) << r.output;
    EXPECT_FALSE(fs::exists(out));
    for (const auto& entry : fs::directory_iterator(s_dir->path()))
        EXPECT_THAT(entry.path().filename().string(), Not(HasSubstr("failed.btfpkg")))
            << "a temporary output was left behind";
}

TEST_F(Mpi, CompressManyWritesTheGoodMaterialsAndReportsTheBadOne) {
    ASSERT_EQ(test::run("synth --preset woven_fabric --size 16 -o " + at("w.h5")).code, 0);
    ASSERT_EQ(test::run("synth --preset brushed_metal --size 12 -o " + at("b.h5")).code, 0);
    test::write_file(at("bad.h5"), "not an HDF5 file");
    test::write_file(at("list.txt"), "# the database\nm.h5\nw.h5\n\nbad.h5\nb.h5\n");
    const std::string dir = at("many");
    const test::CliResult r =
        launch(2, "compress-many " + at("list.txt") + " -p components=4 --no-error -o " + dir);
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_THAT(r.output, HasSubstr("3 of 4 materials written to " + dir + " by 2 MPI ranks"));
    EXPECT_THAT(r.output, HasSubstr("failed: " + at("bad.h5")));
    EXPECT_THAT(r.output, HasSubstr("1 of 4 materials failed"));
    for (const char* name : {"m", "w", "b"}) {
        const std::string pkg = (fs::path(dir) / (std::string(name) + ".btfpkg")).string();
        ASSERT_TRUE(fs::exists(pkg)) << name;
        EXPECT_EQ(open_package_source(pkg)->num_views(), 81) << name;
    }
    EXPECT_FALSE(fs::exists(fs::path(dir) / "bad.btfpkg"));
    // The largest (m, 24²) goes to rank 0, the other two to rank 1, which has less to do.
    EXPECT_THAT(r.output, testing::ContainsRegex(at("m.h5") + " +0 "));
    EXPECT_THAT(r.output, testing::ContainsRegex(at("w.h5") + " +1 "));
    EXPECT_THAT(r.output, testing::ContainsRegex(at("b.h5") + " +1 "));
}

TEST_F(Mpi, CompressManyRunsInOneProcessToo) {
    const std::string dir = at("many1");
    const test::CliResult r =
        test::run("compress-many " + at("m.h5") + " --codec mlvq --no-error -o " + dir);
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("1 of 1 materials written to " + dir + "\n"));
    EXPECT_TRUE(fs::exists(fs::path(dir) / "m.btfpkg"));
}

TEST_F(Mpi, CommandsThatRunInOneProcessAreRefusedAcrossRanks) {
    test::CliResult r = launch(2, "info " + at("m.h5"));
    EXPECT_NE(r.code, 0);
    EXPECT_THAT(r.output, HasSubstr("btf info runs in one process: start it without mpirun"));
    r = launch(2, "compress " + at("m.h5") + " --codec mlvq -o " + at("mlvq.btfpkg"));
    EXPECT_NE(r.code, 0);
    EXPECT_THAT(r.output, HasSubstr("codec mlvq runs in one process"));
    EXPECT_FALSE(fs::exists(at("mlvq.btfpkg")));
}

}  // namespace
}  // namespace btf
