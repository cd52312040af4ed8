// SPDX-License-Identifier: MIT
// UBO2003 import throughput on the real measured view (../shared/data/ubo2003-proposte-view000:
// 81 progressive JPEGs, 256×256): opening (names + every image header), and reading all 81
// images through BtfSource::read_image (read the JPEG bytes, decode, sRGB → linear float), from
// the extracted folder and from a zip archive of it (entries stored, as the database's archives
// are; the archive is built in a temporary folder at start-up). Single thread (a plain loop) and
// all threads (parallel_for over the 81 images). Rates: MB/s of JPEG file bytes read and decoded
// (10^6 bytes), images/s. BM_ImportSingleThreadRaw keeps the 8-bit code values (no sRGB
// decoding) to show what the colour conversion costs.
//
//   build/<dir>/ubo2003_import_bench --benchmark_min_time=2

#include <benchmark/benchmark.h>
#include <unistd.h>
#include <zip.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "btf/io/ubo2003.h"
#include "btf/util/parallel.h"

namespace {

namespace fs = std::filesystem;

const fs::path kRealView = fs::path(BTF_SHARED_DIR) / "data/ubo2003-proposte-view000/tv000_pv000";

// The JPEG bytes of the real view, and a stored zip of it (removed at exit).
struct Data {
    bool present = false;
    uint64_t jpeg_bytes = 0;
    fs::path temp;
    fs::path archive;

    Data() {
        std::error_code ec;
        if (!fs::is_directory(kRealView, ec)) return;
        temp = fs::temp_directory_path() / ("btf_ubo2003_bench_" + std::to_string(::getpid()));
        fs::create_directories(temp);
        archive = temp / "UBO_PROPOSTE_view000.zip";
        std::map<std::string, std::vector<char>> files;
        for (const auto& entry : fs::directory_iterator(kRealView)) {
            std::ifstream in(entry.path(), std::ios::binary);
            files["PROPOSTE/tv000_pv000/" + entry.path().filename().string()] =
                std::vector<char>(std::istreambuf_iterator<char>(in), {});
            jpeg_bytes += entry.file_size();
        }
        int error = 0;
        zip_t* za = zip_open(archive.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
        if (!za) return;
        for (const auto& [name, bytes] : files) {
            const zip_int64_t index = zip_file_add(
                za, name.c_str(), zip_source_buffer(za, bytes.data(), bytes.size(), 0), 0);
            zip_set_file_compression(za, zip_uint64_t(index), ZIP_CM_STORE, 0);
        }
        present = zip_close(za) == 0;
    }
    ~Data() {
        std::error_code ec;
        if (!temp.empty()) fs::remove_all(temp, ec);
    }
};

const Data& data() {
    static const Data instance;
    return instance;
}

const fs::path& path_of(int zip) {
    return zip ? data().archive : kRealView;
}

void set_rates(benchmark::State& state) {
    state.counters["MB/s"] = benchmark::Counter(double(data().jpeg_bytes) / 1e6,
                                                benchmark::Counter::kIsIterationInvariantRate);
    state.counters["images/s"] =
        benchmark::Counter(81, benchmark::Counter::kIsIterationInvariantRate);
}

// Arg 0: extracted folder, 1: zip archive.
void BM_Open(benchmark::State& state) {
    if (!data().present) return state.SkipWithError("real UBO2003 view not found");
    for (auto _ : state) benchmark::DoNotOptimize(btf::ubo2003::open(path_of(state.range(0))));
}

void BM_ImportSingleThread(benchmark::State& state) {
    if (!data().present) return state.SkipWithError("real UBO2003 view not found");
    auto source = btf::ubo2003::open(path_of(state.range(0)));
    btf::Image image;
    for (auto _ : state)
        for (int l = 0; l < 81; ++l) {
            source->read_image(0, l, image);
            benchmark::DoNotOptimize(image.data());
        }
    set_rates(state);
}

// Single thread, code values kept (Encoding::kRaw): the difference to BM_ImportSingleThread is
// the cost of the sRGB → linear decoding.
void BM_ImportSingleThreadRaw(benchmark::State& state) {
    if (!data().present) return state.SkipWithError("real UBO2003 view not found");
    btf::OpenOptions options;
    options.encoding = btf::Encoding::kRaw;
    auto source = btf::ubo2003::open(path_of(state.range(0)), options);
    btf::Image image;
    for (auto _ : state)
        for (int l = 0; l < 81; ++l) {
            source->read_image(0, l, image);
            benchmark::DoNotOptimize(image.data());
        }
    set_rates(state);
}

void BM_ImportAllThreads(benchmark::State& state) {
    if (!data().present) return state.SkipWithError("real UBO2003 view not found");
    auto source = btf::ubo2003::open(path_of(state.range(0)));
    std::vector<btf::Image> images(81);
    for (auto _ : state) {
        btf::parallel_for(0, 81, [&](int64_t l) { source->read_image(0, int(l), images[l]); });
        benchmark::DoNotOptimize(images.data());
    }
    set_rates(state);
}

BENCHMARK(BM_Open)->ArgName("zip")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ImportSingleThread)
    ->ArgName("zip")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_ImportSingleThreadRaw)
    ->ArgName("zip")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_ImportAllThreads)
    ->ArgName("zip")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
