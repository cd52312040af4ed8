// SPDX-License-Identifier: MIT
// Write and read speed of btfkit's HDF5 form (btf::h5) for a 64×64-texel BTF with 81 views × 81
// lights (UBO2003 sampling; 322 MB as float32 RGB). Prints a Markdown table for
// docs/benchmarks.md. Speeds are in MB/s of the raw BTF as float32 RGB (raw_bytes()), so half and
// float32 files compare by the data they carry.
//
// The "photo" source crops the 81 real UBO2003 photographs in BTF_SHARED_DIR/data (one per light;
// the crop moves with the view), so compression sees measured noise; it costs a copy per image.
// The "slow" source computes every value (a few transcendental functions), like a decoder would,
// to show what reading the source in parallel buys.
//
//   build/<dir>/h5_speed [folder for the temporary files, default /tmp] [side, default 64]

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <thread>
#include <vector>

#include "btf/core/image.h"
#include "btf/io/h5.h"
#include "btf/util/parallel.h"

namespace {

namespace fs = std::filesystem;

/// A procedural BTF: smooth texture × angular lobe, cheap (a few ns per value) so the numbers
/// measure the HDF5 path; `costly` adds per-value transcendental work, like a decoder would.
class Procedural : public btf::BtfSource {
  public:
    Procedural(int side, bool costly) : m_side(side), m_costly(costly) {
        m_sampling.views = btf::DirectionSet::ubo81();
        m_sampling.lights = btf::DirectionSet::ubo81();
        m_info.format = "procedural";
    }
    int width() const override { return m_side; }
    int height() const override { return m_side; }
    const btf::Sampling& sampling() const override { return m_sampling; }
    const btf::SourceInfo& info() const override { return m_info; }
    void read_image(int view, int light, btf::Image& out) const override {
        out.reshape(m_side, m_side, 3);
        const btf::Vec3 wo = m_sampling.views.vector(view), wi = m_sampling.lights.vector(light);
        const float lobe = float(0.2 + 0.8 * std::pow(std::max(0.0, btf::dot(wi, wo)), 8.0));
        float* p = out.data();
        for (int y = 0; y < m_side; ++y)
            for (int x = 0; x < m_side; ++x)
                for (int c = 0; c < 3; ++c) {
                    float v = lobe * (0.3f + 0.002f * float((x * 7 + y * 13 + c * 5) % 97));
                    if (m_costly) v *= std::exp(0.01f * std::sin(0.1f * float(x + y + c)));
                    *p++ = v;
                }
    }

  private:
    int m_side;
    bool m_costly;
    btf::Sampling m_sampling;
    btf::SourceInfo m_info;
};

/// Crops of real photographs (see the top of this file).
class Photo : public btf::BtfSource {
  public:
    Photo(int side, const fs::path& folder) : m_side(side) {
        std::vector<fs::path> files;
        for (const auto& entry : fs::directory_iterator(folder))
            if (entry.path().extension() == ".jpg") files.push_back(entry.path());
        std::sort(files.begin(), files.end());
        for (const fs::path& f : files) m_photos.push_back(btf::read_image(f));
        m_sampling.views = btf::DirectionSet::ubo81();
        m_sampling.lights = btf::DirectionSet::ubo81();
        m_info.format = "photo crops";
    }
    bool usable() const {
        return m_photos.size() == 81 && m_photos[0].width() >= m_side + 81 &&
               m_photos[0].height() >= m_side + 81;
    }
    int width() const override { return m_side; }
    int height() const override { return m_side; }
    const btf::Sampling& sampling() const override { return m_sampling; }
    const btf::SourceInfo& info() const override { return m_info; }
    void read_image(int view, int light, btf::Image& out) const override {
        out.reshape(m_side, m_side, 3);
        const btf::Image& photo = m_photos[size_t(light)];
        for (int y = 0; y < m_side; ++y)
            std::copy_n(&photo.values()[(size_t(y + view) * photo.width() + view) * 3],
                        size_t(m_side) * 3, &out.values()[size_t(y) * m_side * 3]);
    }

  private:
    int m_side;
    std::vector<btf::Image> m_photos;
    btf::Sampling m_sampling;
    btf::SourceInfo m_info;
};

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
    const fs::path folder = argc > 1 ? fs::path(argv[1]) : fs::path("/tmp");
    const int side = argc > 2 ? std::atoi(argv[2]) : 64;
    const fs::path file = folder / fmt::format("btf_h5_speed_{}.h5", ::getpid());
    const Procedural cheap(side, false), costly(side, true);
    const double raw_mb = double(cheap.raw_bytes()) / 1e6;
    const fs::path photos = fs::path(BTF_SHARED_DIR) / "data/ubo2003-proposte-view000/tv000_pv000";
    std::unique_ptr<Photo> photo;
    if (fs::is_directory(photos)) photo = std::make_unique<Photo>(side, photos);
    if (photo && !photo->usable()) photo.reset();
    const btf::BtfSource& data = photo ? static_cast<const btf::BtfSource&>(*photo) : cheap;
    const char* data_name = photo ? "photo" : "procedural (photos not found)";

    fmt::print(
        "btf::h5 speed: {0}×{0} texels, 81 views × 81 lights, {1:.0f} MB as float32 RGB; "
        "{2} hardware threads; MB/s of float32 data\n\n",
        side, raw_mb, std::thread::hardware_concurrency());
    fmt::print(
        "| case | threads | write s | write MB/s | file MB | read s (1 thread) | read MB/s "
        "(1 thread) | read s (all threads) | read MB/s (all threads) |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|\n");

    struct Case {
        std::string name;
        const btf::BtfSource* source;
        bool half;
        int deflate;
        int threads;  // 0 = all
    };
    const std::string d = data_name;
    const Case cases[] = {
        {d + ", float16", &data, true, 0, 0},
        {d + ", float16", &data, true, 0, 1},
        {d + ", float32", &data, false, 0, 0},
        {d + ", float16, shuffle + deflate 1", &data, true, 1, 0},
        {d + ", float16, shuffle + deflate 1", &data, true, 1, 1},
        {d + ", float16, shuffle + deflate 6", &data, true, 6, 0},
        {"slow source, float16", &costly, true, 0, 0},
        {"slow source, float16", &costly, true, 0, 1},
    };
    for (const Case& c : cases) {
        btf::h5::WriteOptions options;
        options.half = c.half;
        options.deflate = c.deflate;
        double write_s = 0;
        {
            btf::ThreadLimit limit(c.threads);
            const auto start = std::chrono::steady_clock::now();
            btf::h5::write(*c.source, file, options);
            write_s = seconds_since(start);
        }
        const double file_mb = double(fs::file_size(file)) / 1e6;
        const auto source = btf::h5::open(file);
        const int n_lights = source->num_lights();
        const int64_t n_images = source->sampling().num_images();

        auto start = std::chrono::steady_clock::now();
        btf::Image image;
        for (int64_t i = 0; i < n_images; ++i)
            source->read_image(int(i / n_lights), int(i % n_lights), image);
        const double read1_s = seconds_since(start);

        start = std::chrono::steady_clock::now();
        btf::parallel_for(0, n_images, [&](int64_t i) {
            thread_local btf::Image local;
            source->read_image(int(i / n_lights), int(i % n_lights), local);
        });
        const double read_all_s = seconds_since(start);

        fmt::print("| {} | {} | {:.2f} | {:.0f} | {:.1f} | {:.2f} | {:.0f} | {:.2f} | {:.0f} |\n",
                   c.name, c.threads == 0 ? "all" : "1", write_s, raw_mb / write_s, file_mb,
                   read1_s, raw_mb / read1_s, read_all_s, raw_mb / read_all_s);
        fs::remove(file);
    }
    return 0;
}
