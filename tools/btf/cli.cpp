// SPDX-License-Identifier: MIT
#include "cli.h"

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>

#include "btf/codecs/codec.h"
#include "btf/codecs/dfmf_export.h"
#include "btf/codecs/material_source.h"
#include "btf/io/h5.h"
#include "btf/io/package.h"
#include "btf/io/ubo2014.h"
#include "btf/io/utia.h"
#include "btf/stream/catalog.h"
#include "btf/synth/synth.h"
#include "btf/util/error.h"
#include "btf/version.h"
#include "mpi_world.h"

namespace btf::cli {

namespace fs = std::filesystem;

namespace {

class Bar {
  public:
    explicit Bar(bool terminal) : m_terminal(terminal) {}

    void update(std::string_view stage, uint64_t done, uint64_t total) {
        const auto now = std::chrono::steady_clock::now();
        if (stage != m_stage) {
            if (m_terminal && !m_stage.empty()) std::fputc('\n', stderr);
            m_stage = stage;
            m_start = now;
            m_last_decile = -1;
        }
        const double fraction = total ? double(done) / double(total) : 0.0;
        const double elapsed = std::chrono::duration<double>(now - m_start).count();
        std::string eta = "--:--";
        if (done > 0 && total > 0 && done < total) {
            const int seconds = int(elapsed * (double(total - done) / double(done)));
            eta = fmt::format("{}:{:02}", seconds / 60, seconds % 60);
        } else if (done >= total && total > 0) {
            eta = fmt::format("{:.1f}s", elapsed);
        }
        if (m_terminal) {
            constexpr int kWidth = 30;
            const int filled = int(fraction * kWidth);
            std::string bar(size_t(filled), '=');
            if (filled < kWidth) bar += '>' + std::string(size_t(kWidth - filled - 1), ' ');
            std::fprintf(stderr, "\r%-22.22s [%s] %3d%% %llu/%llu %s   ", m_stage.c_str(),
                         bar.c_str(), int(fraction * 100), (unsigned long long)done,
                         (unsigned long long)total, eta.c_str());
            if (done >= total && total > 0) {
                std::fputc('\n', stderr);
                m_stage.clear();
            }
        } else {
            const int decile = int(fraction * 10);
            if (decile != m_last_decile) {
                m_last_decile = decile;
                std::fprintf(stderr, "%s: %d%% (%llu/%llu) %s\n", m_stage.c_str(), decile * 10,
                             (unsigned long long)done, (unsigned long long)total, eta.c_str());
            }
        }
        std::fflush(stderr);
    }

  private:
    bool m_terminal;
    std::string m_stage;
    std::chrono::steady_clock::time_point m_start;
    int m_last_decile = -1;
};

}  // namespace

Progress make_progress(const GlobalOptions& options) {
    // Across MPI ranks, rank 0 speaks for all (each rank reports its own share of the work).
    if (options.quiet || mpi_rank() != 0) return Progress();
    auto bar = std::make_shared<Bar>(::isatty(2) != 0);
    return Progress([bar](std::string_view stage, uint64_t done, uint64_t total) {
        bar->update(stage, done, total);
    });
}

namespace {
std::vector<double> parse_numbers(const std::string& text, const std::string& option) {
    std::vector<double> numbers;
    size_t start = 0;
    while (start <= text.size()) {
        size_t end = text.find(',', start);
        if (end == std::string::npos) end = text.size();
        std::string field = text.substr(start, end - start);
        while (!field.empty() && field.front() == ' ') field.erase(field.begin());
        while (!field.empty() && field.back() == ' ') field.pop_back();
        double value = 0;
        auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
        if (field.empty() || ec != std::errc() || ptr != field.data() + field.size() ||
            !std::isfinite(value))
            fail("{}: '{}' is not a comma-separated list of numbers", option, text);
        numbers.push_back(value);
        start = end + 1;
    }
    return numbers;
}
}  // namespace

Direction parse_direction(const std::string& text, const std::string& option) {
    const std::vector<double> v = parse_numbers(text, option);
    if (v.size() != 2) fail("{}: expected 'theta,phi' in degrees, got '{}'", option, text);
    if (v[0] < 0 || v[0] > 90) fail("{}: theta {} is outside [0, 90] degrees", option, v[0]);
    return Direction::from_degrees(v[0], v[1]);
}

std::pair<int, int> parse_pair(const std::string& text, const std::string& option) {
    const std::vector<double> v = parse_numbers(text, option);
    auto is_int = [](double d) { return d == std::floor(d) && std::abs(d) <= 1e9; };
    if (v.size() != 2 || !is_int(v[0]) || !is_int(v[1]))
        fail("{}: expected two integers 'x,y', got '{}'", option, text);
    return {int(v[0]), int(v[1])};
}

std::vector<int> parse_indices(const std::string& text, const std::string& option) {
    std::vector<int> indices;
    for (double v : parse_numbers(text, option)) {
        if (v != std::floor(v) || v < 0 || v > 1e6)
            fail("{}: '{}' is not a list of indices", option, text);
        indices.push_back(int(v));
    }
    return indices;
}

Uv parse_uv(const std::string& text, const std::string& option) {
    const std::vector<double> v = parse_numbers(text, option);
    if (v.size() != 2) fail("{}: expected texture coordinates 'u,v', got '{}'", option, text);
    return {v[0], v[1]};
}

std::string format_ratio(double ratio) {
    return ratio >= 10 ? fmt::format("{:.0f}:1", ratio) : fmt::format("{:.1f}:1", ratio);
}

std::filesystem::path default_web_dir() {
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        const std::filesystem::path installed = exe.parent_path() / BTF_BIN_TO_WEB;
        if (std::filesystem::is_regular_file(installed / "index.html", ec)) return installed;
    }
    return BTF_WEB_DIR;
}

std::string version_line() {
    const std::string commit = build_commit();
    return commit.empty() ? writer_name() : fmt::format("{} (git {})", writer_name(), commit);
}

std::string human_bytes(double bytes) {
    const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
    int u = 0;
    while (bytes >= 1024 && u < 4) bytes /= 1024, ++u;
    return u == 0 ? fmt::format("{:.0f} B", bytes) : fmt::format("{:.1f} {}", bytes, units[u]);
}

void add_open_options(CLI::App& command, OpenOptions& options, std::string& views_text) {
    command.add_option("--views", views_text,
                       "open only these views: comma-separated indices into the format's view set");
    command.add_flag_callback(
        "--raw", [&options] { options.encoding = Encoding::kRaw; },
        "keep 8-bit code values instead of decoding sRGB to linear");
}

OpenOptions finish_open_options(OpenOptions options, const std::string& views_text) {
    if (!views_text.empty()) options.views = parse_indices(views_text, "--views");
    return options;
}

std::unique_ptr<Material> open_material_file(const std::string& path) {
    // A UBO2014 file: the material of its own factors, the same as its package's.
    if (probe_package(path) || ubo2014::probe(path))
        return open_material(std::filesystem::path(path));
    if (!std::filesystem::exists(path)) fail("{}: no such file", path);
    fail("{}: not a btfkit package or UBO2014 .btf file", path);
}

std::unique_ptr<BtfSource> open_input(const std::string& path, const OpenOptions& options,
                                      const std::string& views_text) {
    if (probe_package(path) && (!views_text.empty() || options.encoding != Encoding::kLinear))
        fail("{}: --views and --raw do not apply to a btfkit package", path);
    return open_package_or_source(path, finish_open_options(options, views_text));
}

std::string lower_extension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

OutputKind output_kind(const std::string& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".h5" || ext == ".hdf5") return OutputKind::kHdf5;
    if (ext == ".btf") return OutputKind::kDfmf;
    if (ext == ".btfpkg") return OutputKind::kPackage;
    if (ext.empty()) return OutputKind::kFolder;
    return OutputKind::kOther;
}

void add_raw_output_options(CLI::App& command, RawOutputOptions& options) {
    command
        .add_option("--format", options.format,
                    "UTIA image format: png (8-bit sRGB) or exr (half float XYZ); default png, "
                    "exr for HDR sources")
        ->check(CLI::IsMember({"png", "exr"}));
    command.add_flag("--float", options.use_float, "HDF5: store float32 instead of half floats");
    command.add_option("--deflate", options.deflate, "HDF5: deflate level 0-9 (0 = uncompressed)")
        ->check(CLI::Range(0, 9));
}

void write_raw(const BtfSource& source, const std::string& output, const RawOutputOptions& options,
               Progress& progress) {
    write_source(source, output, {!options.use_float, options.deflate, options.format}, progress);
}

fs::path cache_folder() {
    if (const char* dir = std::getenv("BTF_CACHE_DIR"); dir && *dir) return dir;
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg == '/')
        return fs::path(xdg) / "btfkit";
    if (const char* home = std::getenv("HOME"); home && *home)
        return fs::path(home) / ".cache" / "btfkit";
    fail("no cache folder: set BTF_CACHE_DIR (or HOME)");
}

fs::path demo_package(const GlobalOptions& global) {
    constexpr int kSize = 128;
    const fs::path folder = cache_folder() / "demo";
    const fs::path path = folder / "woven_fabric.btfpkg";
    std::error_code ec;
    if (fs::exists(path, ec)) {
        try {
            const stream::CatalogEntry entry = stream::describe_package(path);
            if (entry.codec == "fmf" && entry.width == kSize && entry.height == kSize &&
                entry.views == 81 && entry.lights == 81)
                return path;
        } catch (const Cancelled&) {
            throw;
        } catch (const Error&) {
            // Damaged: made again below.
        }
    }
    fs::create_directories(folder, ec);
    if (ec) fail("{}: cannot create the cache folder: {}", folder.string(), ec.message());
    if (!global.quiet)
        std::fprintf(stderr,
                     "btf: making the demo material (woven_fabric, %dx%d texels, fmf) in "
                     "%s; later starts reuse it\n",
                     kSize, kSize, folder.string().c_str());
    const DirectionSet& set = DirectionSet::ubo81();
    const auto source = synth::make("woven_fabric", kSize, Sampling{set, set}, 1);
    Progress progress = make_progress(global);
    Package package = find_codec("fmf").encode(
        *source, Params{{"components", "32"}, {"quantize", "f16"}}, progress);
    // Written to a temporary name and renamed: a second server starting at the same time, or an
    // interrupted first start, never sees a partial file.
    write_package(path, package, {}, progress);
    return path;
}

void write_ubo2014_package(const std::string& input, const fs::path& output,
                           const GlobalOptions& global) {
    Progress progress = make_progress(global);
    Package package = package_of(*ubo2014::read(input, progress), input);
    write_package(output, package, {}, progress);
}

std::vector<fs::path> servable_inputs(const std::vector<std::string>& inputs,
                                      const GlobalOptions& global) {
    std::vector<fs::path> out;
    for (const std::string& input : inputs) {
        std::error_code ec;
        if (!fs::is_regular_file(input, ec) || !ubo2014::probe(input)) {
            out.emplace_back(input);
            continue;
        }
        const fs::path canonical = fs::canonical(input, ec);
        const auto size = fs::file_size(input, ec);
        const auto time = fs::last_write_time(input, ec).time_since_epoch().count();
        const size_t key = std::hash<std::string>{}(
            fmt::format("{}\n{}\n{}", canonical.string(), size, int64_t(time)));
        const fs::path package = cache_folder() / "ubo2014" / fmt::format("{:016x}", key) /
                                 (fs::path(input).stem().string() + ".btfpkg");
        if (!fs::exists(package, ec)) {
            fs::create_directories(package.parent_path(), ec);
            if (ec)
                fail("{}: cannot create the cache folder: {}", package.parent_path().string(),
                     ec.message());
            write_ubo2014_package(input, package, global);
        }
        out.push_back(package);
    }
    return out;
}

}  // namespace btf::cli
