// SPDX-License-Identifier: MIT
// End-to-end tests of the `btf` command: what a user types, what they get back.

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "btf/core/image.h"
#include "btf/io/open.h"
#include "btf/io/package.h"
#include "btf/testing/cli.h"
#include "btf/testing/support.h"
#include "btf/util/clones.h"
#include "btf/util/thin_products.h"
#include "btf/version.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

using test::CliResult;
using test::run;

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
    const char* subs[] = {"info",   "convert", "synth", "slice",  "compress", "decompress", "eval",
                          "render", "report",  "serve", "bundle", "codecs",   "formats"};
    for (const char* sub : subs) EXPECT_NE(r.output.find(sub), std::string::npos) << sub;
    for (const char* sub : subs) EXPECT_EQ(run(std::string(sub) + " --help").code, 0) << sub;
}

// The version declared in CMakeLists.txt, with the commit of the checkout it was built from (CI
// and `make test` build from one), in `btf --version` and in the header of every package.
TEST_F(BtfCli, VersionAndPackageWriterAreTheProjectVersion) {
    const CliResult r = run("--version");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_THAT(r.output, ::testing::MatchesRegex("btfkit " BTF_PROJECT_VERSION
                                                  "( \\(git [0-9a-f]{12}(-modified)?\\))?\n"));
    EXPECT_EQ(btf::version(), std::string(BTF_PROJECT_VERSION));

    const std::string source = path("writer.h5"), package = path("writer.btfpkg");
    ASSERT_EQ(run("-q synth --preset woven_fabric --size 8 -o " + source).code, 0);
    const CliResult c =
        run("-q compress " + source + " -o " + package + " --codec fmf --components 2 --no-error");
    ASSERT_EQ(c.code, 0) << c.output;
    EXPECT_EQ(btf::read_package(package).header["writer"], "btfkit " BTF_PROJECT_VERSION);
}

TEST_F(BtfCli, VerboseNamesTheOpenBlasKernelAndTheThreads) {
    const CliResult r = run("--verbose --threads 1 codecs");
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find(fmt::format("btf: 1 worker threads; evaluators: {}; factorization "
                                        "products: {}; OpenBLAS ",
                                        btf::clone_level(),
                                        btf::thin::kernel() == btf::thin::Kernel::kOwn
                                            ? "btfkit's AVX-512 kernels"
                                            : "OpenBLAS")),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find(", kernel "), std::string::npos) << r.output;
    EXPECT_EQ(run("codecs").output.find("kernel"), std::string::npos);
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

TEST_F(BtfCli, AnHdf5FileThatCrashesLibhdf5GivesOneLine) {
    // libhdf5 1.10 crashes reading this file's root attributes; btf reads it in a child process.
    const fs::path damaged =
        fs::path(BTF_SOURCE_DIR) / "fuzz/regressions/hdf5/global-heap-read-overflow.h5";
    for (const std::string& command :
         std::vector<std::string>{"info ", "compress --codec fmf -o " + path("x.btfpkg") + " "}) {
        const CliResult r = run(command + damaged.string());
        EXPECT_EQ(r.code, 1) << r.output;
        // Crashed, or killed after looping (as under AddressSanitizer): named either way.
        EXPECT_NE(r.output.find("global-heap-read-overflow.h5: libhdf5 "), std::string::npos)
            << r.output;
        EXPECT_NE(r.output.find("the input is damaged or crafted"), std::string::npos) << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        EXPECT_FALSE(fs::exists(path("x.btfpkg")));
    }
}

// Runs `btf ARGS` in the background (stderr to `log`), waits until `ready` (a shell condition)
// holds, then stops it, sends `signals` (TERM, INT, …) and lets it go on: the process cannot have
// finished before the signals arrive, however fast or busy the machine. Returns its exit status;
// 120 s without readiness is a hang guard, not a timing assertion.
int interrupted(const std::string& args, const fs::path& log, const std::string& ready,
                const std::vector<std::string>& signals) {
    std::string kills;
    for (const std::string& s : signals) kills += "kill -" + s + " $pid; ";
    const std::string script = fmt::format(
        "{} {} 2> '{}' & pid=$!; i=0; "
        "until {}; do sleep 0.05; i=$((i+1)); if [ $i -gt 2400 ]; then break; fi; done; "
        "kill -STOP $pid; {}kill -CONT $pid; wait $pid",
        BTF_TOOL_PATH, args, log.string(), ready, kills);
    const int status = std::system(script.c_str());  // /bin/sh -c SCRIPT
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST_F(BtfCli, InterruptedRunLeavesNoFiles) {
    // SIGTERM while the output is being written (its temporary file exists): the run unwinds,
    // removes the temporary and exits 130.
    const fs::path dir = s_dir / "interrupt";
    fs::create_directories(dir);
    const int code =
        interrupted("--quiet synth --preset leather --size 256 -o " + (dir / "big.h5").string(),
                    s_dir / "interrupt.log", "ls -A " + dir.string() + " | grep -q tmp", {"TERM"});
    EXPECT_EQ(code, 130);
    EXPECT_TRUE(fs::is_empty(dir)) << "left behind: " << fs::directory_iterator(dir)->path();
}

TEST_F(BtfCli, InterruptedCompressionLeavesNoFilesAndKeepsTheOldOutput) {
    // SIGINT while compress reads its source (its progress says so), and SIGINT then SIGTERM (the
    // second signal ends the process at once, through the watchdog): both
    // stop the run with 130, and the package that was there before is untouched. The source is
    // 128² so that the run lasts seconds after its first progress line: the process must still be
    // running when the shell stops it, however busy the machine (64² finished first once, with a
    // benchmark compressing beside it).
    const fs::path dir = s_dir / "interrupt_compress";
    fs::create_directories(dir);
    const std::string source = (dir / "src.h5").string();
    ASSERT_EQ(run("synth --preset woven_fabric --size 128 -o " + source).code, 0);
    const fs::path out = dir / "out.btfpkg";
    test::write_file(out, "what the user had");
    for (const std::vector<std::string>& signals :
         {std::vector<std::string>{"INT"}, std::vector<std::string>{"INT", "TERM"}}) {
        const fs::path log = s_dir / "compress.log";
        const int code = interrupted(
            "compress " + source + " -o " + out.string() + " --codec fmf -p components=8", log,
            "grep -q . '" + log.string() + "'", signals);
        EXPECT_EQ(code, 130) << test::read_file(log);
        EXPECT_EQ(test::read_file(out), "what the user had");
        std::vector<std::string> left;
        for (const auto& entry : fs::directory_iterator(dir))
            left.push_back(entry.path().filename());
        EXPECT_EQ(left.size(), 2u) << fmt::format("{}", fmt::join(left, ", "));
    }
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

// Root-mean-square difference of two sources over every sample.
double rmse(const BtfSource& a, const BtfSource& b) {
    double sum = 0;
    int64_t count = 0;
    for (int v = 0; v < a.num_views(); ++v)
        for (int l = 0; l < a.num_lights(); ++l) {
            const Image x = a.image(v, l), y = b.image(v, l);
            for (size_t i = 0; i < x.values().size(); ++i) {
                const double d = double(x.values()[i]) - y.values()[i];
                sum += d * d;
            }
            count += int64_t(x.values().size());
        }
    return std::sqrt(sum / double(count));
}

// Writes a 7-direction set (lights and views: 49 images keep the tests fast).
std::string write_small_directions(const std::string& file) {
    std::ofstream(file) << "0 0\n30 0\n30 120\n30 240\n60 60\n60 180\n60 300\n";
    return file;
}

// The codecs `btf codecs` lists, with the parameter names of each.
std::vector<std::pair<std::string, std::vector<std::string>>> listed_codecs() {
    const CliResult r = run("codecs");
    EXPECT_EQ(r.code, 0) << r.output;
    std::vector<std::pair<std::string, std::vector<std::string>>> out;
    std::istringstream lines(r.output);
    std::string line;
    while (std::getline(lines, line)) {
        if (line.empty()) continue;
        std::istringstream words(line);
        std::string first;
        words >> first;
        if (line[0] != ' ') {
            std::string description;
            std::getline(words, description);
            EXPECT_GT(description.size(), 10u) << "codec " << first << " has no description";
            out.push_back({first, {}});
        } else if (!out.empty()) {
            // "    key=default  help"
            const size_t eq = first.find('=');
            EXPECT_NE(eq, std::string::npos) << line;
            out.back().second.push_back(first.substr(0, eq));
        }
    }
    return out;
}

TEST_F(BtfCli, CompressWithEveryCodecThenDecompressEvalInfo) {
    const std::string h5 = path("tiny.h5");
    CliResult r = run("synth --preset leather --size 16 --seed 2 --float --sampling " +
                      write_small_directions(path("dirs.txt")) + " -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    const auto original = open_source(h5);
    ASSERT_EQ(original->num_views(), 7);

    const auto codecs = listed_codecs();
    ASSERT_FALSE(codecs.empty());
    EXPECT_EQ(codecs[0].first, "fmf");
    const std::regex summary(
        R"((\S+): [0-9.]+ (B|KiB|MiB), ratio ([0-9.]+):1 \(vs 8-bit RGB raw\), RMSE ([0-9.e+-]+), )"
        R"(encoded in [0-9.]+ s\n)");
    for (const auto& [codec, params] : codecs) {
        SCOPED_TRACE(codec);
        const std::string package = path("c_" + codec + ".btfpkg");
        std::string args = "compress " + h5 + " -o " + package + " --codec " + codec;
        if (std::find(params.begin(), params.end(), "components") != params.end())
            args += " --components 4";
        r = run(args);
        ASSERT_EQ(r.code, 0) << r.output;
        std::smatch m;
        ASSERT_TRUE(std::regex_search(r.output, m, summary)) << r.output;
        EXPECT_EQ(m[1].str(), package);
        const double ratio = std::stod(m[3].str()), printed_rmse = std::stod(m[4].str());
        // 16² texels × 49 images × 3 bytes = 37632 bytes raw.
        EXPECT_NEAR(ratio, 37632.0 / double(fs::file_size(package)), 0.051) << r.output;
        EXPECT_GT(printed_rmse, 0.0);
        EXPECT_LT(printed_rmse, 0.1) << r.output;

        // Decompressed (float32), the samples are exactly what the RMSE was measured on.
        const std::string decoded = path("d_" + codec + ".h5");
        r = run("decompress " + package + " -o " + decoded + " --float");
        ASSERT_EQ(r.code, 0) << r.output;
        const auto back = open_source(decoded);
        ASSERT_EQ(back->width(), 16);
        ASSERT_EQ(back->num_views(), 7);
        ASSERT_EQ(back->num_lights(), 7);
        EXPECT_NEAR(rmse(*original, *back), printed_rmse, 0.005 * printed_rmse + 1e-6);

        // At a texel centre and measured directions, eval returns that same sample.
        const int view = original->sampling().views.find(Direction::from_degrees(60, 180));
        const int light = original->sampling().lights.find(Direction::from_degrees(30, 120));
        ASSERT_GE(view, 0);
        ASSERT_GE(light, 0);
        r = run("eval " + package + " --uv " + std::to_string(5.5 / 16) + "," +
                std::to_string(9.5 / 16) + " --light 30,120 --view 60,180");
        ASSERT_EQ(r.code, 0) << r.output;
        std::istringstream numbers(r.output);
        double rgb[3] = {-1, -1, -1};
        numbers >> rgb[0] >> rgb[1] >> rgb[2];
        ASSERT_FALSE(numbers.fail()) << r.output;
        std::string rest;
        numbers >> rest;
        EXPECT_TRUE(rest.empty()) << r.output;
        const Rgb expected = back->image(view, light).rgb(5, 9);
        EXPECT_NEAR(rgb[0], expected.r, 1e-4 + 1e-4 * std::abs(expected.r)) << r.output;
        EXPECT_NEAR(rgb[1], expected.g, 1e-4 + 1e-4 * std::abs(expected.g)) << r.output;
        EXPECT_NEAR(rgb[2], expected.b, 1e-4 + 1e-4 * std::abs(expected.b)) << r.output;

        r = run("info " + package);
        ASSERT_EQ(r.code, 0) << r.output;
        EXPECT_NE(r.output.find("btfkit package, codec " + codec), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("16 x 16 texels"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("(complete)"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("vs 8-bit RGB raw"), std::string::npos) << r.output;
    }
}

TEST_F(BtfCli, InfoOnAPackagePrefix) {
    const std::string h5 = path("prefix.h5");
    CliResult r = run("synth --preset leather --size 16 --seed 4 --sampling " +
                      write_small_directions(path("dirs.txt")) + " -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string package = path("full.btfpkg");
    r = run("compress " + h5 + " -o " + package + " --codec fmf --components 6 --quantize u8");
    ASSERT_EQ(r.code, 0) << r.output;

    r = run("info " + package);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("components=6"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("quantization u8"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("7 (dirs)"), std::string::npos) << r.output;

    // Cut the file after its third section: a valid prefix, fewer components.
    const Package full = read_package(package);
    ASSERT_GT(full.declared_sections, 3);
    std::ifstream in(package, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_GE(bytes.size(), size_t(kPackagePreamble));
    uint32_t header_bytes = 0;
    for (int i = 0; i < 4; ++i) header_bytes |= uint32_t(uint8_t(bytes[12 + i])) << (8 * i);
    const PackageSection& third = full.sections[2];
    const size_t cut = kPackagePreamble + header_bytes + third.offset + third.stored_size;
    ASSERT_LT(cut, bytes.size());
    const std::string prefix = path("prefix.btfpkg");
    std::ofstream(prefix, std::ios::binary).write(bytes.data(), std::streamsize(cut));

    r = run("info " + prefix);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find(fmt::format("3 of {}: a prefix", full.declared_sections)),
              std::string::npos)
        << r.output;
    r = run("info --json " + prefix);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("\"prefix\": true"), std::string::npos) << r.output;
    r = run("eval " + prefix + " --uv 0.5,0.5 --light 30,0 --view 0,0");
    EXPECT_EQ(r.code, 0) << r.output;

    // A cut inside a section is damage, not a prefix.
    std::ofstream(path("cut.btfpkg"), std::ios::binary)
        .write(bytes.data(), std::streamsize(cut - 1));
    r = run("info " + path("cut.btfpkg"));
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_NE(r.output.find("cut.btfpkg"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

TEST_F(BtfCli, CompressErrorsGiveOneLineAndNoFile) {
    const std::string h5 = path("err.h5");
    CliResult r = run("synth --preset leather --size 8 --sampling " +
                      write_small_directions(path("dirs.txt")) + " -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string out = path("err.btfpkg");
    auto expect_error = [&](const std::string& args, const std::string& message) {
        const CliResult e = run(args);
        EXPECT_EQ(e.code, 1) << args << "\n" << e.output;
        EXPECT_NE(e.output.find(message), std::string::npos) << e.output;
        EXPECT_EQ(std::count(e.output.begin(), e.output.end(), '\n'), 1) << e.output;
        EXPECT_FALSE(fs::exists(out)) << args;
    };
    expect_error("compress " + h5 + " -o " + out + " --codec nope",
                 "unknown codec 'nope' (known: fmf");
    expect_error("compress " + h5 + " -o " + out + " --codec fmf -p bogus=1",
                 "codec fmf: unknown parameter 'bogus' (known: components");
    expect_error("compress " + h5 + " -o " + out + " -p components", "expected key=value");
    expect_error("compress " + h5 + " -o " + out + " --components 4 -p components=5",
                 "give it once");
    expect_error("compress " + h5 + " -o " + out + " -p colour=purple",
                 "parameter colour: 'purple' is not one of");
    expect_error("compress " + path("missing.h5") + " -o " + out, "no such file or folder");
    expect_error("compress " + h5 + " " + h5 + " -o " + out + " --codec fmf",
                 "codec fmf compresses one input; several inputs share code-books only with mlvq");
    r = run("compress " + h5 + " -o " + path("err.h5.out"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("name the output *.btfpkg"), std::string::npos) << r.output;
    r = run("decompress " + h5 + " -o " + path("d.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_FALSE(fs::exists(path("d.h5")));
    r = run("eval " + h5 + " --uv 0,0 --light 0,0 --view 0,0");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("not a btfkit package or UBO2014 .btf file"), std::string::npos)
        << r.output;
}

// mlvq: several inputs share one set of code-books; info shows them as Table 3 of the paper.
TEST_F(BtfCli, MlvqSharesCodeBooksBetweenInputs) {
    const std::string a = path("a.h5"), b = path("b.h5"), out = path("shared.btfpkg");
    const std::string dirs = write_small_directions(path("dirs.txt"));
    ASSERT_EQ(run("synth --preset leather --size 8 --sampling " + dirs + " -o " + a).code, 0);
    ASSERT_EQ(run("synth --preset woven_fabric --size 8 --sampling " + dirs + " -o " + b).code, 0);
    CliResult r = run("compress " + a + " " + b + " -o " + out +
                      " --codec mlvq -p n-alpha=5 -p n-beta=5 -p n-theta-v=3 -p n-phi-v=4");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find(", 2 materials, encoded in "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("  " + a + ": RMSE "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("  " + b + ": RMSE "), std::string::npos) << r.output;
    r = run("info " + out);
    ASSERT_EQ(r.code, 0) << r.output;
    for (const char* row : {"materials    2 sharing the code-books", "  P1 ", "  P4 ", "  I2 ",
                            "C.R.1 (32-bit indices and floats)", "C.R.4 (both; as stored)"})
        EXPECT_NE(r.output.find(row), std::string::npos) << row << "\n" << r.output;
}

TEST_F(BtfCli, ConvertToDfmfThroughFmf) {
    const std::string h5 = path("dfmf.h5");
    CliResult r = run("synth --preset leather --size 16 --seed 5 --sampling " +
                      write_small_directions(path("dirs.txt")) + " -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    for (const char* colour : {"model11", "rgb"}) {
        SCOPED_TRACE(colour);
        const std::string btf = path(std::string("out_") + colour + ".btf");
        r = run("convert " + h5 + " " + btf + " --components 8 --colour " + colour);
        ASSERT_EQ(r.code, 0) << r.output;
        r = run("info " + btf);
        ASSERT_EQ(r.code, 0) << r.output;
        EXPECT_NE(r.output.find("UBO2014"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("16 x 16 texels"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("views        7 ("), std::string::npos) << r.output;
        // 8 of 49 components per channel keep the synthetic material close.
        const auto original = open_source(h5), back = open_source(btf);
        EXPECT_LT(rmse(*original, *back), 0.05);
        r = run("eval " + btf + " --uv 0.3,0.6 --light 45,30 --view 10,0");
        EXPECT_EQ(r.code, 0) << r.output;
    }
}

// A UBO2014 file's own factors as an fmf package: DFMF files of the repository's writer, colour
// models 0 and 11 in half and float, evaluate like the file at sample directions and texel
// centres (between them the package interpolates the colour planes, the file decoded values).
TEST_F(BtfCli, ConvertsAUbo2014FileToAPackageWithoutRefactorizing) {
    const std::string h5 = path("u.h5");
    CliResult r = run("synth --preset leather --size 16 --seed 3 --sampling " +
                      write_small_directions(path("dirs.txt")) + " -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    for (const std::string colour : {"model11", "rgb"})
        for (const std::string half : {"", " --half"}) {
            SCOPED_TRACE(colour + half);
            const std::string btf = path("u.btf"), pkg = path("u.btfpkg");
            r = run("convert " + h5 + " " + btf + " --components 6 --colour " + colour + half);
            ASSERT_EQ(r.code, 0) << r.output;
            r = run("convert " + btf + " " + pkg);
            ASSERT_EQ(r.code, 0) << r.output;
            r = run("info " + pkg);
            ASSERT_EQ(r.code, 0) << r.output;
            EXPECT_NE(r.output.find("fmf"), std::string::npos) << r.output;
            for (const char* query : {" --uv 0.03125,0.96875 --light 30,120 --view 0,0",
                                      " --uv 0.53125,0.28125 --light 60,300 --view 30,240"}) {
                const CliResult file = run("eval " + btf + query);
                const CliResult package = run("eval " + pkg + query);
                ASSERT_EQ(file.code, 0) << file.output;
                ASSERT_EQ(package.code, 0) << package.output;
                double a[3], b[3];
                ASSERT_EQ(std::sscanf(file.output.c_str(), "%lf %lf %lf", &a[0], &a[1], &a[2]), 3);
                ASSERT_EQ(std::sscanf(package.output.c_str(), "%lf %lf %lf", &b[0], &b[1], &b[2]),
                          3);
                for (int c = 0; c < 3; ++c)
                    EXPECT_NEAR(b[c], a[c], 1e-4 * std::max(std::abs(a[c]), 1e-2)) << query;
            }
        }
    // Other inputs: one line, no package.
    r = run("convert " + h5 + " " + path("x.btfpkg"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("u.h5: btf convert writes a package only from a UBO2014 .btf file"),
              std::string::npos)
        << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(path("x.btfpkg")));
}

TEST_F(BtfCli, BenchMeasuresEvalAndSampleOfAnyMaterial) {
    // Counts and fields, not speeds: a busy machine may be slow.
    const std::string h5 = path("bench.h5"), pkg = path("bench.btfpkg"), btf = path("bench.btf");
    ASSERT_EQ(run("synth --preset leather --size 8 --sampling " +
                  write_small_directions(path("bdirs.txt")) + " -o " + h5)
                  .code,
              0);
    ASSERT_EQ(run("compress " + h5 + " --codec fmf --components 3 --no-error -o " + pkg).code, 0);
    ASSERT_EQ(run("convert " + h5 + " " + btf + " --components 3").code, 0);
    for (const std::string what : {"eval", "sample", "eval-sample"})
        for (const std::string& file : {pkg, btf})
            for (const std::string mode : {"", " --coherent"})
                for (const std::string filter : {"stochastic", "deterministic"}) {
                    if (what == "eval-sample" && (!mode.empty() || filter != "stochastic"))
                        continue;  // no directions and no filter
                    SCOPED_TRACE(what + " " + file + mode + " " + filter);
                    const CliResult r =
                        run("-q bench " + what + " " + file + " --filter " + filter +
                            " --queries 5000 --repeat 2 --threads 2 --json" + mode);
                    ASSERT_EQ(r.code, 0) << r.output;
                    const nlohmann::json j = nlohmann::json::parse(r.output);
                    EXPECT_EQ(j.at("queries"), 5000);
                    EXPECT_EQ(j.at("threads"), 2);
                    EXPECT_EQ(j.at("repeat"), 2);
                    EXPECT_EQ(j.at("mode"), mode.empty() ? "random" : "coherent");
                    EXPECT_EQ(j.at("filter"), what == "eval-sample" ? "none" : filter);
                    EXPECT_GT(
                        j.at(what == "sample" ? "samples_per_s" : "evals_per_s").get<double>(), 0);
                    EXPECT_GT(j.at("checksum").get<double>(), 0);
                }
    const CliResult line = run("-q bench eval " + pkg + " --queries 1000 --repeat 1");
    ASSERT_EQ(line.code, 0) << line.output;
    EXPECT_TRUE(std::regex_search(
        line.output,
        std::regex(R"(bench\.btfpkg: eval [0-9.]+ M/s \(random, filter stochastic, 1 thread, 1000 )"
                   R"(queries, best of 1\)\n$)")))
        << line.output;
    const CliResult bad = run("bench eval " + pkg + " --filter bilinear");
    EXPECT_NE(bad.code, 0);
    EXPECT_THAT(bad.output, testing::HasSubstr("--filter"));
    const CliResult missing = run("bench eval " + path("none.btfpkg"));
    EXPECT_NE(missing.code, 0);
    EXPECT_THAT(missing.output, testing::HasSubstr("none.btfpkg: no such file"));
}

TEST_F(BtfCli, EvalOfAUbo2014FileAndOfItsPackagePrintTheSameValues) {
    // Between sample directions and texel centres too: `btf eval X.btf` is the fmf evaluator of
    // the file's own factors, which is what the package holds.
    const std::string h5 = path("e.h5");
    CliResult r = run("synth --preset woven_fabric --size 8 --seed 5 --sampling " +
                      write_small_directions(path("edirs.txt")) + " -o " + h5);
    ASSERT_EQ(r.code, 0) << r.output;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> unit(0, 1);
    std::vector<std::string> queries;
    for (int i = 0; i < 200; ++i) {
        // uv beyond [0, 1) (the material wraps), every third light and fifth view grazing.
        const double light_theta = i % 3 == 0 ? 85 + 5 * unit(rng) : 85 * unit(rng);
        const double view_theta = i % 5 == 0 ? 85 + 5 * unit(rng) : 85 * unit(rng);
        queries.push_back(fmt::format("{:.5f},{:.5f} {:.3f},{:.3f} {:.3f},{:.3f}",
                                      -1 + 3 * unit(rng), -1 + 3 * unit(rng), light_theta,
                                      360 * unit(rng), view_theta, 360 * unit(rng)));
    }
    const std::string list = path("queries.txt");
    std::ofstream(list) << "# u,v light view\n" << fmt::format("{}\n", fmt::join(queries, "\n"));
    const auto values = [](const std::string& text) {
        std::vector<double> out;
        std::istringstream in(text);
        for (double x; in >> x;) out.push_back(x);
        return out;
    };
    for (const std::string colour : {"model11", "rgb"})
        for (const std::string half : {"", " --half"}) {
            SCOPED_TRACE(colour + half);
            const std::string btf = path("e.btf"), pkg = path("e.btfpkg");
            r = run("convert " + h5 + " " + btf + " --components 4 --colour " + colour + half);
            ASSERT_EQ(r.code, 0) << r.output;
            r = run("convert " + btf + " " + pkg);
            ASSERT_EQ(r.code, 0) << r.output;
            const CliResult file = run("eval " + btf + " --queries " + list);
            const CliResult package = run("eval " + pkg + " --queries " + list);
            ASSERT_EQ(file.code, 0) << file.output;
            ASSERT_EQ(package.code, 0) << package.output;
            const std::vector<double> a = values(file.output), b = values(package.output);
            ASSERT_EQ(a.size(), 3 * queries.size()) << file.output;
            ASSERT_EQ(b.size(), 3 * queries.size()) << package.output;
            for (size_t i = 0; i < a.size(); ++i)
                EXPECT_NEAR(a[i], b[i], 1e-4 * std::abs(b[i]) + 1e-6) << queries[i / 3];
            // One query given as options prints what its line of the list prints.
            std::istringstream fields(queries[7]);
            std::string uv, light, view;
            fields >> uv >> light >> view;
            r = run("eval " + btf + " --uv " + uv + " --light " + light + " --view " + view);
            ASSERT_EQ(r.code, 0) << r.output;
            const std::vector<double> one = values(r.output);
            ASSERT_EQ(one.size(), 3u) << r.output;
            for (int c = 0; c < 3; ++c) EXPECT_EQ(one[size_t(c)], a[size_t(21 + c)]);
        }
    // A malformed line: one line naming the file and the line, nothing printed.
    std::ofstream(path("bad.txt")) << "0.5,0.5 30,0 0,0\n0.5,0.5 30,0\n";
    r = run("eval " + path("e.btf") + " --queries " + path("bad.txt"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("bad.txt: line 2: expected 'u,v theta,phi theta,phi'"),
              std::string::npos)
        << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

}  // namespace
}  // namespace btf
