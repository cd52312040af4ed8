// SPDX-License-Identifier: MIT
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
#include <immintrin.h>
#include <malloc.h>
#include <sys/mman.h>
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
#include "btf/codecs/factor/params.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/io/h5.h"
#include "btf/io/open.h"
#include "btf/synth/synth.h"
#include "btf/util/blas.h"
#include "btf/util/half.h"
#include "btf/util/huge_pages.h"
#include "btf/util/parallel.h"
#include "btf/util/thin_products.h"

namespace {

using namespace btf;
namespace fs = std::filesystem;

// Logs each stage's duration to stderr (the passes of the factorization).
class StageLog {
  public:
    StageLog()
        : m_progress([this](std::string_view stage, uint64_t, uint64_t) {
              if (stage == m_stage) return;
              if (!m_stage.empty()) {
                  std::fprintf(stderr, "  %s: %.1f s\n", m_stage.c_str(), m_clock.seconds());
                  m_summary += fmt::format("{}{} {:.1f} s", m_summary.empty() ? "" : "; ", m_stage,
                                           m_clock.seconds());
              }
              m_stage = std::string(stage);
              m_clock = bench::Stopwatch();
          }) {}
    Progress& progress() { return m_progress; }
    /// "pass 1 of 4: 3.1 s, …" for the stages logged so far.
    std::string summary() const { return m_summary; }

  private:
    std::string m_summary;
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

// madvise(MADV_HUGEPAGE) over the 2 MiB-aligned interior of [p, p + bytes).
void advise_huge_pages(void* p, size_t bytes) {
    const uintptr_t begin =
        (reinterpret_cast<uintptr_t>(p) + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
    const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(kHugePageBytes - 1);
    if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
}

// Reads a C-order float32 .npy file of two dimensions (as write_npy writes it).
factor::Matrix read_npy(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[10];
    in.read(magic, 10);
    if (!in || std::string(magic, 6) != "\x93NUMPY" || magic[6] != 1)
        fail("{}: not a version 1 .npy file", path.string());
    const uint16_t length = uint16_t(uint8_t(magic[8])) | uint16_t(uint8_t(magic[9])) << 8;
    std::string header(length, '\0');
    in.read(header.data(), length);
    long long rows = 0, cols = 0;
    if (header.find("'<f4'") == std::string::npos ||
        header.find("'fortran_order': False") == std::string::npos ||
        std::sscanf(header.c_str() + header.find("'shape': (") + 10, "%lld, %lld", &rows, &cols) !=
            2)
        fail("{}: expected a C-order float32 matrix", path.string());
    factor::Matrix m(rows, cols);
    // Transparent huge pages for the matrix, as NumPy gives its large arrays (madvise, before
    // the first touch): the passes stream 5 GB, which 4 KiB pages cover only with TLB misses.
    advise_huge_pages(m.data(), size_t(m.size()) * sizeof(float));
    in.read(reinterpret_cast<char*>(m.data()), std::streamsize(m.size() * sizeof(float)));
    if (!in) fail("{}: truncated", path.string());
    return m;
}

std::vector<std::string> split(const std::string& text, char separator) {
    std::vector<std::string> out;
    size_t begin = 0;
    while (begin <= text.size()) {
        const size_t end = std::min(text.find(separator, begin), text.size());
        if (end > begin) out.push_back(text.substr(begin, end - begin));
        begin = end + 1;
    }
    return out;
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
    fs::path matrix_path, h5_given;
    std::string configs = "subspace:3,krylov:3";
    double exact = 0;
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
    app.add_option("--matrix", matrix_path,
                   "(b): the matrix as a float32 .npy file instead of making it");
    app.add_option("--configs", configs,
                   "(b): btfkit's configurations, method:q[:block[:oversampling]], comma-separated")
        ->capture_default_str();
    std::string products = "default";
    app.add_option("--products", products,
                   "(b): thin products by avx512 (btfkit's kernels), openblas, or both, "
                   "comma-separated; each configuration runs with each")
        ->capture_default_str();
    app.add_option("--exact", exact,
                   "(b): the Eckart–Young relative error of the matrix (bench/exact_tail.py)");
    app.add_option("--h5", h5_given, "(a): an existing btfkit HDF5 file instead of synthesizing");
    CLI11_PARSE(app, argc, argv);
    const std::string tag = fmt::format("btfkit_fmf_speed_{}", ::getpid());
    fs::path h5_path = dir / (tag + ".h5");
    const fs::path npy_path = dir / (tag + ".npy"), out_prefix = dir / (tag + "_sklearn");
    auto cleanup = [&] {
        std::error_code ec;
        if (h5_given.empty()) fs::remove(h5_path, ec);
        fs::remove(npy_path, ec);
        for (const char* ext : {".u", ".s", ".vt", ".json"})
            fs::remove(out_prefix.string() + ext, ec);
    };
    try {
        const fmf::Options defaults;
        const DirectionSet& ubo = DirectionSet::ubo81();
        if (!h5_given.empty()) {
            h5_path = h5_given;
        } else if (part != "b" || matrix_path.empty()) {
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
            const factor::SvdOptions svd = factor::svd_options(defaults, components, false);
            const int passes = factor::svd_passes(svd);
            std::printf(
                "(a) end to end: %s, %d² texels × %d views × %d lights in a btfkit HDF5 file (%.2f "
                "GB) → fmf C = %d (rgb, %s, q = %d, oversampling %d: %d passes; f16, zstd 9); "
                "products: %s; %s\n\n",
                h5_path.filename().c_str(), source->width(), source->num_views(),
                source->num_lights(), double(fs::file_size(h5_path)) / 1e9, components,
                defaults.svd == factor::SvdMethod::kBlockKrylov ? "block Krylov" : "subspace",
                defaults.power_iterations, defaults.oversampling, passes,
                std::string(thin::kernel_name()).c_str(), blas::description().c_str());
            std::printf(
                "| wall time | peak RSS | peak RSS above start | package | ratio (8-bit RGB) |\n"
                "|---|---|---|---|---|\n");
            std::printf("| %.1f s | %.0f MiB%s | %.0f MiB | %.2f MB | %.0f:1 |\n\n", seconds,
                        bench::mib(peak), reset ? "" : " (whole process)",
                        bench::mib(peak - rss_before), double(bytes.size()) / 1e6,
                        raw8 / double(bytes.size()));
            std::fflush(stdout);

            // One pass split: reading (HDF5 and half → float in the reader, rgb rows: one pass of
            // fmf's row batches over the file, without products), of which conversion (the same
            // number of halves converted in memory), and the rest of a pass (products).
            std::vector<int> all(source->num_views());
            for (int v = 0; v < source->num_views(); ++v) all[v] = v;
            const factor::SourceRows rows(*source, factor::ColourHandling{}, {all});
            std::vector<int64_t> first;
            std::vector<factor::Matrix> batch;
            clock = bench::Stopwatch();
            for (int b = 0; b < rows.batches(); ++b) rows.read(b, first, batch);
            const double read_seconds = clock.seconds();
            std::vector<uint16_t> halves(size_t(source->num_texels()) * 3 * source->num_lights());
            for (size_t i = 0; i < halves.size(); ++i) halves[i] = to_half(float(i % 977) / 977);
            std::vector<float> floats(halves.size());
            clock = bench::Stopwatch();
            for (int v = 0; v < source->num_views(); ++v)
                parallel_chunks(0, int64_t(halves.size()), 1 << 16, [&](int64_t b, int64_t e) {
                    // F16C, as the HDF5 reader converts (io/h5.cpp).
                    int64_t i = b;
                    for (; i + 8 <= e; i += 8)
                        _mm256_storeu_ps(floats.data() + i,
                                         _mm256_cvtph_ps(_mm_loadu_si128(
                                             reinterpret_cast<const __m128i*>(&halves[i]))));
                    for (; i < e; ++i) floats[i] = from_half(halves[i]);
                });
            const double convert_seconds = clock.seconds();
            std::printf(
                "Per pass: reading %.2f s (`SourceRows::read` over the file: HDF5, half → float, "
                "rgb rows), of which half → float (F16C, as the reader converts, on a pass's "
                "values in memory) %.2f s; products and the rest %.2f s (the wall time over %d "
                "passes, less reading). Stages: %s.\n\n",
                read_seconds, convert_seconds, seconds / passes - read_seconds, passes,
                log.summary().c_str());
            std::fflush(stdout);
        }

        if (part.find('b') != std::string::npos) {
            // The matrix, exactly as fmf reads it (rgb rows, one view's 243 rows per batch), or
            // as given.
            factor::Matrix m;
            fs::path npy = npy_path;
            if (!matrix_path.empty()) {
                bench::Stopwatch clock;
                m = read_npy(matrix_path);
                npy = matrix_path;
                std::fprintf(stderr, "read %s in %.1f s\n", matrix_path.c_str(), clock.seconds());
            } else {
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
                std::error_code ec;
                if (h5_given.empty()) fs::remove(h5_path, ec);
                clock = bench::Stopwatch();
                write_npy(npy_path, m);
                std::fprintf(stderr, "wrote %s in %.1f s\n", npy_path.c_str(), clock.seconds());
            }
            const double total = squared_norm(m);
            const double mn2 = 2.0 * double(m.rows()) * double(m.cols());  // flops per column

            std::printf(
                "(b) in memory: the %lld × %lld float32 matrix (%.2f GB), rank %d; %d cores; "
                "%s; btfkit's thin products by default: %s\n\n",
                static_cast<long long>(m.rows()), static_cast<long long>(m.cols()),
                double(m.size()) * 4 / 1e9, components, int(std::thread::hardware_concurrency()),
                blas::description().c_str(), std::string(thin::kernel_name()).c_str());
            std::printf(
                "| implementation | passes | products (columns) | time | GFLOP/s | rel. error "
                "‖M − USVᵀ‖/‖M‖ |%s peak memory above the matrix |\n|---|---|---|---|---|---|%s---|"
                "\n",
                exact > 0 ? " × Eckart–Young |" : "", exact > 0 ? "---|" : "");
            const int64_t rss_loaded = bench::current_rss();
            struct Ours {
                std::string name;
                double seconds, error;
            };
            std::vector<Ours> ours;
            std::vector<thin::Kernel> kernels;
            for (const std::string& name : split(products, ',')) {
                if (name == "default")
                    kernels.push_back(thin::kernel());
                else if (name == "avx512")
                    kernels.push_back(thin::Kernel::kOwn);
                else if (name == "openblas")
                    kernels.push_back(thin::Kernel::kBlas);
                else
                    fail("--products: {}: expected avx512, openblas or default", name);
            }
            for (const std::string& spec : split(configs, ','))
                for (const thin::Kernel kernel : kernels) {
                    thin::set_kernel(kernel);
                    const bench::SvdConfig config = bench::parse_svd_config(spec);
                    factor::SvdOptions options;
                    options.rank = components;
                    options.seed = defaults.seed;
                    options.method = config.method;
                    options.power_iterations =
                        config.power_iterations >= 0 ? config.power_iterations : 3;
                    options.block = std::max(config.block, 0);
                    options.oversampling =
                        config.oversampling >= 0 ? config.oversampling : defaults.oversampling;
                    const int passes = factor::svd_passes(options);
                    const int l = options.rank + options.oversampling;
                    const int q = options.power_iterations;
                    const int b = options.block > 0 ? options.block : (2 * l + q + 1) / (q + 2);
                    const int columns = options.method == factor::SvdMethod::kSubspace
                                            ? (2 + 2 * q) * l
                                            : (2 * (q + 1) + 1) * b;
                    bench::reset_peak_rss();
                    StageLog log;
                    bench::Stopwatch clock;
                    const factor::MemoryRows rows({&m}, 243);
                    const factor::Svd svd =
                        factor::randomized_svd(rows, options, log.progress()).at(0);
                    const double seconds = clock.seconds();
                    log.progress().begin("done", 0);
                    const int64_t peak = bench::peak_rss();
                    const double error =
                        std::sqrt(residual_energy(m, svd.u, svd.sigma, svd.v) / total);
                    const std::string name =
                        (options.method == factor::SvdMethod::kSubspace
                             ? fmt::format("btfkit subspace, q = {}, oversampling {}", q,
                                           options.oversampling)
                             : fmt::format("btfkit krylov, q = {}, block {}", q, b)) +
                        fmt::format(" ({})", thin::kernel_name());
                    std::printf("| %s | %d | %d | %.2f s | %.0f | %.5f |%s %.0f MiB |\n",
                                name.c_str(), passes, columns, seconds,
                                columns * mn2 / seconds / 1e9, error,
                                exact > 0 ? fmt::format(" {:.4f} |", error / exact).c_str() : "",
                                bench::mib(peak - rss_loaded));
                    std::fflush(stdout);
                    ours.push_back({name, seconds, error});
                }

            // scikit-learn on the same matrix (a missing python3 or scikit-learn skips the row).
            const int sk_q = 3, sk_p = 10, sk_l = components + sk_p;
            const std::string command =
                fmt::format("'{}' '{}' '{}' '{}' {} {} {}", python, script.string(), npy.string(),
                            out_prefix.string(), components, sk_q, sk_p);
            bench::Stopwatch clock;
            const int status = std::system(command.c_str());
            const double python_wall = clock.seconds();
            std::error_code ec;
            fs::remove(npy_path, ec);
            if (status != 0) {
                std::printf("| scikit-learn: `%s` failed (exit status %d): skipped |\n",
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
                const int columns = (2 + 2 * sk_q) * sk_l;
                std::printf(
                    "| scikit-learn `randomized_svd`, n_iter = %d, n_oversamples = %d, QR "
                    "(OpenBLAS, %s threads) | %d | %d | %.2f s | %.0f | %.5f |%s %.0f MiB |\n\n",
                    sk_q, sk_p, result.at("threads").dump().c_str(), 2 + 2 * sk_q, columns,
                    their_seconds, columns * mn2 / their_seconds / 1e9, their_error,
                    exact > 0 ? fmt::format(" {:.4f} |", their_error / exact).c_str() : "",
                    bench::mib(their_extra));
                std::printf(
                    "| btfkit configuration | speed against scikit-learn (target ≥ 2.5×) | error "
                    "against scikit-learn's (target ≤ 1) |\n|---|---|---|\n");
                for (const Ours& o : ours)
                    std::printf("| %s | **%.2f×** | %.5f |\n", o.name.c_str(),
                                their_seconds / o.seconds, o.error / their_error);
                std::printf("\nPython process wall time (load + call + write): %.1f s.\n",
                            python_wall);
            }
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
