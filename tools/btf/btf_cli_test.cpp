// End-to-end tests of the `btf` command: what a user types, what they get back.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

#include "btf/core/image.h"
#include "btf/io/open.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

struct CliResult {
    int code = -1;
    std::string output;  // stdout and stderr together
};

CliResult run(const std::string& args) {
    const std::string command = std::string(BTF_TOOL_PATH) + " --quiet " + args + " 2>&1";
    CliResult result;
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) return result;
    std::array<char, 4096> buffer;
    size_t n;
    while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
        result.output.append(buffer.data(), n);
    const int status = ::pclose(pipe);
    result.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return result;
}

class BtfCli : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        // CTest runs each test in its own process, concurrently: one folder per process.
        s_dir = fs::path(testing::TempDir()) / ("btf_cli_test_" + std::to_string(::getpid()));
        fs::remove_all(s_dir);
        fs::create_directories(s_dir);
    }
    static void TearDownTestSuite() { fs::remove_all(s_dir); }
    static std::string path(const std::string& name) { return (s_dir / name).string(); }
    static fs::path s_dir;
};
fs::path BtfCli::s_dir;

TEST_F(BtfCli, HelpListsEverySubcommand) {
    const CliResult r = run("--help");
    EXPECT_EQ(r.code, 0);
    for (const char* sub : {"info", "convert", "synth", "slice", "formats"})
        EXPECT_NE(r.output.find(sub), std::string::npos) << sub;
    for (const char* sub : {"info", "convert", "synth", "slice", "formats"})
        EXPECT_EQ(run(std::string(sub) + " --help").code, 0) << sub;
}

TEST_F(BtfCli, BadInputGivesOneLineAndNonZeroExit) {
    CliResult r = run("info " + path("missing.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("missing.h5: no such file or folder"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;

    r = run("synth --preset no-such-preset --size 8 -o " + path("x.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("no-such-preset"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(path("x.h5")));

    // Arguments are checked before the (possibly slow) opening of the input.
    r = run("slice " + path("missing.h5") + " --light 100,0 --view 0,0 -o " + path("s.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--light: theta 100 is outside [0, 90] degrees"), std::string::npos)
        << r.output;
    EXPECT_FALSE(fs::exists(path("s.png")));
    r = run("slice " + path("missing.h5") + " --texel 1e10,0 -o " + path("s.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--texel: expected two integers"), std::string::npos) << r.output;

    // Output names that do not say what they are.
    r = run("synth --preset leather --size 8 -o " + path("x.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("name the output *.h5"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(path("x.png")));
    r = run("synth --preset leather --size 8 --sampling " + path("nodirs.txt") + " -o " +
            path("x.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("no such direction-set file"), std::string::npos) << r.output;
}

TEST_F(BtfCli, InterruptedRunLeavesNoFiles) {
    // SIGTERM during a long write: the run unwinds, removes its temporary file and exits 130.
    const fs::path dir = s_dir / "interrupt";
    fs::create_directories(dir);
    const std::string command =
        "sh -c '" + std::string(BTF_TOOL_PATH) + " --quiet synth --preset leather --size 256 -o " +
        (dir / "big.h5").string() + " & pid=$!; sleep 1.5; kill -TERM $pid; wait $pid; exit $?'";
    const int status = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 130);
    EXPECT_TRUE(fs::is_empty(dir)) << "left behind: " << fs::directory_iterator(dir)->path();
}

TEST_F(BtfCli, SynthInfoSliceConvertRoundTrip) {
    const std::string h5 = path("small.h5");
    CliResult r = run("synth --preset woven_fabric --size 16 --seed 3 -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;

    r = run("info " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("16 x 16 texels"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("81 (ubo81)"), std::string::npos) << r.output;

    r = run("info --json --all " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("\"images\": 6561"), std::string::npos) << r.output;

    // An image between sample directions, and a texel's ABRDF.
    r = run("slice " + h5 + " --light 40,10 --view 20,100 -o " + path("slice.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    const Image slice = read_image(path("slice.png"));
    EXPECT_EQ(slice.width(), 16);
    r = run("slice " + h5 + " --texel 3,4 --scale 2 -o " + path("abrdf.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    const Image abrdf = read_image(path("abrdf.png"));
    EXPECT_EQ(abrdf.width(), 81 * 2);
    EXPECT_EQ(abrdf.height(), 81 * 2);

    // To a UTIA image set and back to HDF5: the values survive within 8-bit precision.
    r = run("convert " + h5 + " " + path("utia") + " --views 0,5");
    ASSERT_EQ(r.code, 0) << r.output;
    r = run("convert " + path("utia") + " " + path("back.h5") + " --float");
    ASSERT_EQ(r.code, 0) << r.output;
    const auto original = open_source(h5, OpenOptions{Encoding::kLinear, {5}});
    const auto back = open_source(path("back.h5"));
    ASSERT_EQ(back->num_views(), 2);
    const Image a = original->image(0, 17), b = back->image(1, 17);
    double max_error = 0;
    for (size_t i = 0; i < a.values().size(); ++i)
        max_error = std::max(max_error, double(std::abs(a.values()[i] - b.values()[i])));
    EXPECT_LT(max_error, 0.01);

    r = run("convert " + h5 + " " + path("out.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("unknown output type '.png'"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(path("out.png")));

    // Converting onto an existing folder is refused and leaves it as it was.
    r = run("convert " + h5 + " " + path("utia"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("exists"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace btf
