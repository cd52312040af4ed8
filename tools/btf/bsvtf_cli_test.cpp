// End-to-end tests of `btf bsvtf`: an fmf package becomes a BSVTF file with a summary line of
// sizes and error; other inputs give one line, exit 1 and no output file.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "btf/bsvtf/file.h"
#include "btf/io/package.h"
#include "btf/testing/cli.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using test::run;

TEST(BsvtfCli, PreprocessesAnFmfPackage) {
    const test::TempFolder dir("bsvtf_cli");
    const std::string h5 = (dir.path() / "m.h5").string(), pkg = (dir.path() / "m.btfpkg").string();
    ASSERT_EQ(run("synth --preset woven_fabric --size 64 -o " + h5).code, 0);
    test::CliResult r = run("compress " + h5 + " --codec fmf --components 6 --no-error -o " + pkg);
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string out = (dir.path() / "m.bsvtf").string();
    r = run("bsvtf " + pkg + " -o " + out + " --tile 16 --tile-error 0.02");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("64 × 64 texels, 2 groups of 4 components, 3 levels of 16 × 16 tiles "
                            "(+4 padding): 42 tiles"),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("compressed ("), std::string::npos) << r.output;
    const bsvtf::Bsvtf b = bsvtf::read_bsvtf(read_package(out), out);
    EXPECT_EQ(b.layout.tile_count(), 42u);
    EXPECT_DOUBLE_EQ(b.relative_error, 0.02);

    r = run("bsvtf " + pkg + " -o " + out + " --tile 16 --lossless");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("lossless"), std::string::npos) << r.output;
    EXPECT_EQ(bsvtf::read_bsvtf(read_package(out), out).step, 0.0f);
}

TEST(BsvtfCli, RefusesOtherInputsWithOneLine) {
    const test::TempFolder dir("bsvtf_cli");
    const std::string h5 = (dir.path() / "m.h5").string(), pca = (dir.path() / "p.btfpkg").string();
    ASSERT_EQ(run("synth --preset leather --size 16 -o " + h5).code, 0);
    ASSERT_EQ(run("compress " + h5 + " --codec pca-views --components 2 --no-error -o " + pca).code,
              0);
    const std::string out = (dir.path() / "o.bsvtf").string();
    test::CliResult r = run("bsvtf " + pca + " -o " + out);
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("p.btfpkg: a 'pca-views' package: btf bsvtf needs an fmf package"),
              std::string::npos)
        << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(out));
    r = run("bsvtf " + h5 + " -o " + out);
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("m.h5"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
    // 36 × 36 texels in tiles of 8: 4 levels, so width and height must be divisible by 8.
    ASSERT_EQ(run("synth --preset leather --size 36 -o " + h5).code, 0);
    const std::string fmf = (dir.path() / "f.btfpkg").string();
    ASSERT_EQ(run("compress " + h5 + " --codec fmf --components 2 --no-error -o " + fmf).code, 0);
    r = run("bsvtf " + fmf + " -o " + out + " --tile 8");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("must be divisible by 8"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace btf
