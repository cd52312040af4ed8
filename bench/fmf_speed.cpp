// Compression speed of the fmf codec on a full-size material (default: synthetic woven_fabric,
// 256² texels × 81 views × 81 lights, C = 64 components, rgb mode: a 19683 × 65536 matrix).
//
// (a) End to end, streaming: the material is first written to a btfkit HDF5 file (half floats,
//     not timed); then open the file, fmf encode (2 + 2q passes over the file, one view's images
//     at a time) and serialize the package. Wall time and peak resident memory of that part.
// (b) In memory: the same matrix (fmf's rgb-mode rows, float32, 5.2 GB) held in memory, factorized
//     by btfkit's randomized_svd (MemoryRows, one view's 243 rows per batch, the fmf defaults) and
//     by scikit-learn's sklearn.utils.extmath.randomized_svd with the same rank, oversampling and
//     power iterations (bench/sklearn_rsvd.py, run by python3 on the matrix written as .npy).
//     Both results' relative Frobenius errors ‖M − U S Vᵀ‖ / ‖M‖ are computed here, explicitly,
//     streaming over the matrix. Memory is the peak resident size during the call minus the
//     resident size with the matrix loaded (and the total peak).
//
// Prints Markdown tables for docs/benchmarks.md. Needs about 2 × 5.2 GB of memory and 5.2 GB of
// free space in --dir for (b); the files are removed afterwards.
//
//   build/<dir>/fmf_speed [--size 256] [--preset woven_fabric] [--components 64] [--dir /tmp]
//                         [--python /usr/bin/python3] [--script bench/sklearn_rsvd.py]
//                         [--part a|b|ab]

#include <fmt/format.h>
#include <malloc.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/io/h5.h"
#include "btf/io/open.h"
#include "btf/synth/synth.h"

namespace {

using namespace btf;
namespace fs = std::filesystem;

// Logs each stage's duration to stderr (the passes of the factorization).
class StageLog {
  public:
    StageLog()
        : m_progress([this](std::string_view stage, uint64_t, uint64_t) {
              if (stage == m_stage) return;
              if (!m_stage.empty())
                  std::fprintf(stderr, "  %s: %.1f s\n", m_stage.c_str(), m_clock.seconds());
              m_stage = std::string(stage);
              m_clock = bench::Stopwatch();
          }) {}
    Progress& progress() { return m_progress; }

  private:
    std::string m_stage;
    bench::Stopwatch m_clock;
    Progress m_progress;
};

// Writes a C-order float32 .npy file (format version 1.0).
void write_npy(const fs::path& path, const factor::Matrix& m) {
    std::string header = fmt::format(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {}), }}", m.rows(), m.cols());
    const size_t unpadded = 10 + header.size() + 1;
    header.append((64 - unpadded % 64) % 64, ' ');
    header.push_back('\n');
    std::ofstream out(path, std::ios::binary);
    const uint16_t length = static_cast<uint16_t>(header.size());
    out.write("\x93NUMPY\x01\x00", 8);
    out.write(reinterpret_cast<const char*>(&length), 2);
    out.write(header.data(), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(m.data()), std::streamsize(m.size() * sizeof(float)));
    if (!out) fail("{}: cannot write the matrix", path.string());
}

factor::Matrix read_raw(const fs::path& path, int64_t rows, int64_t cols) {
    factor::Matrix m(rows, cols);
    std::ifstream in(path, std::ios::binary);
    in.read(reinterpret_cast<char*>(m.data()), std::streamsize(m.size() * sizeof(float)));
    if (!in || in.peek() != EOF)
        fail("{}: expected exactly {} × {} float32 values", path.string(), rows, cols);
    return m;
}

// ‖M − U diag(s) Vᵀ‖²_F in double over fixed row chunks (v: cols × k).
double residual_energy(const factor::Matrix& m, const factor::Matrix& u, const Eigen::VectorXf& s,
                       const factor::Matrix& v) {
    constexpr int64_t kChunk = 243;
    const int64_t chunks = (m.rows() + kChunk - 1) / kChunk;
    std::vector<double> sums(chunks, 0.0);
    parallel_for(0, chunks, [&](int64_t c) {
        const int64_t r0 = c * kChunk, n = std::min(kChunk, m.rows() - r0);
        const factor::Matrix us = u.middleRows(r0, n) * s.asDiagonal();
        const factor::Matrix d = m.middleRows(r0, n) - us * v.transpose();
        sums[c] = d.cast<double>().squaredNorm();
    });
    double total = 0;
    for (double x : sums) total += x;
    return total;
}

double squared_norm(const factor::Matrix& m) {
    constexpr int64_t kChunk = 243;
    const int64_t chunks = (m.rows() + kChunk - 1) / kChunk;
    std::vector<double> sums(chunks, 0.0);
    parallel_for(0, chunks, [&](int64_t c) {
        const int64_t r0 = c * kChunk, n = std::min(kChunk, m.rows() - r0);
        sums[c] = m.middleRows(r0, n).cast<double>().squaredNorm();
    });
    double total = 0;
    for (double x : sums) total += x;
    return total;
}

}  // namespace

int main(int argc, char** argv) {
    int size = 256, components = 64;
    std::string preset = "woven_fabric", part = "ab", python = "/usr/bin/python3";
    fs::path dir = "/tmp", script = fs::path(BTF_SOURCE_DIR) / "bench" / "sklearn_rsvd.py";
    CLI::App app{"fmf compression speed, and against scikit-learn (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--components", components, "rank")->capture_default_str();
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--dir", dir, "folder for the temporary files")->capture_default_str();
    app.add_option("--python", python, "Python with scikit-learn")->capture_default_str();
    app.add_option("--script", script, "the scikit-learn side")->capture_default_str();
    app.add_option("--part", part, "a (end to end), b (in memory) or ab")
        ->check(CLI::IsMember({"a", "b", "ab"}))
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    const std::string tag = fmt::format("btfkit_fmf_speed_{}", ::getpid());
    const fs::path h5_path = dir / (tag + ".h5"), npy_path = dir / (tag + ".npy"),
                   out_prefix = dir / (tag + "_sklearn");
    auto cleanup = [&] {
        std::error_code ec;
        for (const fs::path& p : {h5_path, npy_path}) fs::remove(p, ec);
        for (const char* ext : {".u", ".s", ".vt", ".json"})
            fs::remove(out_prefix.string() + ext, ec);
    };
    try {
        const fmf::Options defaults;
        const DirectionSet& ubo = DirectionSet::ubo81();
        {
            bench::Stopwatch clock;
            const auto synth = synth::make(preset, size, {ubo, ubo}, 1);
            h5::write(*synth, h5_path);
            std::fprintf(stderr, "wrote %s (%.2f GB) in %.1f s\n", h5_path.c_str(),
                         double(fs::file_size(h5_path)) / 1e9, clock.seconds());
        }
        malloc_trim(0);

        if (part.find('a') != std::string::npos) {
            const int64_t rss_before = bench::current_rss();
            const bool reset = bench::reset_peak_rss();
            StageLog log;
            bench::Stopwatch clock;
            const auto source = open_source(h5_path);
            Package package = fmf_codec().encode(
                *source, {{"components", std::to_string(components)}}, log.progress());
            const std::vector<uint8_t> bytes = encode_package(package);
            const double seconds = clock.seconds();
            log.progress().begin("done", 0);
            const int64_t peak = bench::peak_rss();
            const double raw8 = double(source->num_texels()) * source->sampling().num_images() * 3;
            std::printf(
                "(a) end to end: %s %d² × 81 × 81 in a btfkit HDF5 file (half floats, %.2f GB) → "
                "fmf C = %d (rgb, q = %d, oversampling %d, f16, zstd 9)\n\n",
                preset.c_str(), size, double(fs::file_size(h5_path)) / 1e9, components,
                defaults.power_iterations, defaults.oversampling);
            std::printf(
                "| wall time | peak RSS | peak RSS above start | package | ratio (8-bit RGB) |\n"
                "|---|---|---|---|---|\n");
            std::printf(
                "| %.1f s (target < 120 s) | %.0f MiB%s | %.0f MiB | %.2f MB | %.0f:1 |\n\n",
                seconds, bench::mib(peak), reset ? "" : " (whole process)",
                bench::mib(peak - rss_before), double(bytes.size()) / 1e6,
                raw8 / double(bytes.size()));
            std::fflush(stdout);

            // What reading alone costs: one pass of fmf's row batches over the file (HDF5 read,
            // half → float, colour conversion into rows), without the products.
            std::vector<int> all(source->num_views());
            for (int v = 0; v < source->num_views(); ++v) all[v] = v;
            const factor::SourceRows rows(*source, factor::ColourHandling{}, {all});
            std::vector<int64_t> first;
            std::vector<factor::Matrix> batch;
            clock = bench::Stopwatch();
            for (int b = 0; b < rows.batches(); ++b) rows.read(b, first, batch);
            const double read_seconds = clock.seconds();
            const int passes = 2 + 2 * defaults.power_iterations;
            std::printf(
                "Reading alone (one pass of `SourceRows::read` over the file: HDF5, half → float, "
                "rgb rows): %.1f s; × %d passes = %.0f s of the %.0f s.\n\n",
                read_seconds, passes, read_seconds * passes, seconds);
            std::fflush(stdout);
        }

        if (part.find('b') != std::string::npos) {
            // The matrix, exactly as fmf reads it (rgb rows, one view's 243 rows per batch).
            factor::Matrix m;
            {
                bench::Stopwatch clock;
                const auto source = open_source(h5_path);
                std::vector<int> all(source->num_views());
                for (int v = 0; v < source->num_views(); ++v) all[v] = v;
                const factor::SourceRows rows(*source, factor::ColourHandling{}, {all});
                m.resize(rows.rows(0), rows.cols(0));
                std::vector<int64_t> first;
                std::vector<factor::Matrix> batch;
                for (int b = 0; b < rows.batches(); ++b) {
                    rows.read(b, first, batch);
                    m.middleRows(first[0], batch[0].rows()) = batch[0];
                }
                std::fprintf(stderr, "matrix %lld × %lld (%.2f GB) read in %.1f s\n",
                             static_cast<long long>(m.rows()), static_cast<long long>(m.cols()),
                             double(m.size()) * 4 / 1e9, clock.seconds());
            }
            std::error_code ec;
            fs::remove(h5_path, ec);
            {
                bench::Stopwatch clock;
                write_npy(npy_path, m);
                std::fprintf(stderr, "wrote %s in %.1f s\n", npy_path.c_str(), clock.seconds());
            }
            const double total = squared_norm(m);

            factor::SvdOptions options;
            options.rank = components;
            options.oversampling = defaults.oversampling;
            options.power_iterations = defaults.power_iterations;
            options.seed = defaults.seed;
            const int64_t rss_loaded = bench::current_rss();
            bench::reset_peak_rss();
            StageLog log;
            bench::Stopwatch clock;
            const factor::MemoryRows rows({&m}, 243);
            const factor::Svd ours = factor::randomized_svd(rows, options, log.progress()).at(0);
            const double our_seconds = clock.seconds();
            log.progress().begin("done", 0);
            const int64_t our_peak = bench::peak_rss();
            const double our_error =
                std::sqrt(residual_energy(m, ours.u, ours.sigma, ours.v) / total);

            // Reference for the floor: one pass Y = M·X as two large row halves (one Eigen GEMM
            // per core), the best case of the products a pass consists of.
            const int width = options.rank + options.oversampling;
            const factor::Matrix x = factor::Matrix::Random(m.cols(), width);
            factor::Matrix y(m.rows(), width);
            clock = bench::Stopwatch();
            const int64_t half = (m.rows() + 1) / 2;
            parallel_for(0, 2, [&](int64_t h) {
                const int64_t r0 = h * half, n = std::min(half, m.rows() - r0);
                y.middleRows(r0, n).noalias() = m.middleRows(r0, n) * x;
            });
            const double gemm_seconds = clock.seconds();

            const double flops = double(2 + 2 * options.power_iterations) * 2.0 * double(m.rows()) *
                                 double(m.cols()) * width;
            std::printf(
                "(b) in memory: the %lld × %lld float32 matrix (%.2f GB), rank %d, oversampling "
                "%d, %d power iterations (%.2f TFLOP in the passes); %d cores\n\n",
                static_cast<long long>(m.rows()), static_cast<long long>(m.cols()),
                double(m.size()) * 4 / 1e9, components, options.oversampling,
                options.power_iterations, flops / 1e12, int(std::thread::hardware_concurrency()));
            std::printf(
                "| implementation | time | GFLOP/s | rel. error ‖M − USVᵀ‖/‖M‖ | peak memory above "
                "the matrix | peak RSS |\n|---|---|---|---|---|---|\n");
            std::printf(
                "| btfkit `randomized_svd` (MemoryRows, 243-row batches) | %.1f s | %.0f | "
                "%.5f | %.0f MiB | %.2f GiB |\n",
                our_seconds, flops / our_seconds / 1e9, our_error,
                bench::mib(our_peak - rss_loaded), bench::gib(our_peak));
            std::fflush(stdout);

            // scikit-learn on the same matrix (a missing python3 or scikit-learn skips the row).
            const std::string command = fmt::format(
                "'{}' '{}' '{}' '{}' {} {} {}", python, script.string(), npy_path.string(),
                out_prefix.string(), components, options.power_iterations, options.oversampling);
            clock = bench::Stopwatch();
            const int status = std::system(command.c_str());
            const double python_wall = clock.seconds();
            fs::remove(npy_path, ec);
            if (status != 0) {
                std::printf("| scikit-learn: `%s` failed (exit status %d): skipped | | | | | |\n",
                            command.c_str(), status);
            } else {
                nlohmann::json result;
                std::ifstream(out_prefix.string() + ".json") >> result;
                const factor::Matrix su =
                    read_raw(out_prefix.string() + ".u", m.rows(), components);
                const factor::Matrix ss = read_raw(out_prefix.string() + ".s", components, 1);
                const factor::Matrix svt =
                    read_raw(out_prefix.string() + ".vt", components, m.cols());
                const Eigen::VectorXf sigma =
                    Eigen::Map<const Eigen::VectorXf>(ss.data(), components);
                const double their_error =
                    std::sqrt(residual_energy(m, su, sigma, svt.transpose()) / total);
                const double their_seconds = result.at("seconds").get<double>();
                const int64_t their_extra = result.at("peak_extra").get<int64_t>();
                std::printf(
                    "| scikit-learn `randomized_svd` (OpenBLAS, %s threads) | %.1f s | %.0f | "
                    "%.5f | %.0f MiB | %.2f GiB |\n",
                    result.at("threads").dump().c_str(), their_seconds, flops / their_seconds / 1e9,
                    their_error, bench::mib(their_extra),
                    bench::gib(result.at("peak").get<int64_t>()));
                std::printf(
                    "| btfkit vs scikit-learn | **%.2f× as fast** (target ≥ 3×) | | error × %.4f | "
                    "memory × %.2f | |\n\n",
                    their_seconds / our_seconds, our_error / their_error,
                    double(our_peak - rss_loaded) / double(their_extra));
            }
            std::printf(
                "Floor: one pass Y = M·X as one Eigen GEMM per core (2 row halves): %.2f s, %.0f "
                "GFLOP/s; × %d passes = %.1f s. Python process wall time (load + call + write): "
                "%.1f s.\n",
                gemm_seconds,
                2.0 * double(m.rows()) * double(m.cols()) * width / gemm_seconds / 1e9,
                2 + 2 * options.power_iterations, gemm_seconds * (2 + 2 * options.power_iterations),
                python_wall);
        }
    } catch (const btf::Error& e) {
        cleanup();
        std::fprintf(stderr, "fmf_speed: %s\n", e.what());
        return 1;
    } catch (const std::exception& e) {
        cleanup();
        std::fprintf(stderr, "fmf_speed: %s\n", e.what());
        return 1;
    }
    cleanup();
    return 0;
}
