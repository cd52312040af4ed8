// SPDX-License-Identifier: MIT
#pragma once
// Helpers shared by the codec benchmark programs (a header, so that the bench/*.cpp glob does not
// turn it into a program of its own): an in-memory source, wall-clock timing, random directions
// and the process's resident memory from /proc/self/status.

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "btf/codecs/factor/rsvd.h"
#include "btf/core/direction.h"
#include "btf/core/material.h"
#include "btf/io/source.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::bench {

/// Seconds since construction (steady clock).
class Stopwatch {
  public:
    Stopwatch() : m_start(std::chrono::steady_clock::now()) {}
    double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    }

  private:
    std::chrono::steady_clock::time_point m_start;
};

/// The best wall time of `repeat` runs of fn: the machine is shared, so the fastest run is the
/// one least disturbed.
inline double best_of(int repeat, const std::function<void()>& fn) {
    double best = INFINITY;
    for (int r = 0; r < repeat; ++r) {
        Stopwatch clock;
        fn();
        best = std::min(best, clock.seconds());
    }
    return best;
}

/// Loads of single random 64-byte lines per second from a buffer of `bytes` bytes, one thread,
/// with the addresses known ahead (independent loads, prefetched 64 ahead): the most random lines
/// per second that code reading that much memory at random places can get on this machine.
inline double random_line_rate(size_t bytes, int repeat) {
    const size_t lines = std::max<size_t>(bytes / 64, 1);
    std::vector<uint64_t> data(lines * 8, 1);
    constexpr size_t kLoads = size_t(1) << 23, kAhead = 64;
    std::vector<uint32_t> index(kLoads + kAhead);
    std::mt19937_64 rng(11);
    for (uint32_t& i : index) i = uint32_t(rng() % lines);
    uint64_t sum = 0;
    const double t = best_of(repeat, [&] {
        for (size_t i = 0; i < kLoads; ++i) {
            __builtin_prefetch(&data[size_t(index[i + kAhead]) * 8]);
            sum += data[size_t(index[i]) * 8];
        }
    });
    if (sum == 0) std::fprintf(stderr, "(no loads)\n");  // keeps the loads
    return double(kLoads) / t;
}

/// The queries of a size × size image of a plane seen under one light and one view: texel-centre
/// uv in row order, all with the same directions (coherent evaluation).
inline std::vector<Query> image_queries(int size, const Vec3& wi, const Vec3& wo) {
    std::vector<Query> image(size_t(size) * size);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x)
            image[size_t(y) * size + x] = {{(x + 0.5) / size, (y + 0.5) / size}, wi, wo};
    return image;
}

/// A double in [0, 1) from the 53 high bits of the generator (the same on every platform).
inline double uniform01(std::mt19937_64& rng) {
    return double(rng() >> 11) * 0x1p-53;
}

/// A direction uniformly distributed over the upper hemisphere (cos θ uniform).
inline Vec3 random_direction(std::mt19937_64& rng) {
    const double theta = std::acos(uniform01(rng)), phi = 2 * kPi * uniform01(rng);
    return Direction{theta, phi}.vector();
}

/// `count` queries with uniformly random uv in [0, 1)² and directions over the upper hemisphere
/// (cos θ uniform), drawn from `rng` (which goes on from there).
inline std::vector<Query> random_queries(size_t count, std::mt19937_64& rng) {
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<Query> queries(count);
    for (Query& q : queries) {
        q.uv = {uni(rng), uni(rng)};
        q.wi = random_direction(rng);
        q.wo = random_direction(rng);
    }
    return queries;
}

/// A field of /proc/self/status in bytes ("VmRSS", "VmHWM"); 0 where it cannot be read.
inline int64_t proc_status_bytes(const std::string& field) {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(field + ":", 0) == 0)
            return std::stoll(line.substr(field.size() + 1)) * 1024;
    return 0;
}

/// Resident memory now.
inline int64_t current_rss() {
    return proc_status_bytes("VmRSS");
}
/// Peak resident memory since the start or the last reset_peak_rss().
inline int64_t peak_rss() {
    return proc_status_bytes("VmHWM");
}
/// Resets the peak to the current resident memory (Linux: "5" into /proc/self/clear_refs), so
/// that the peak of one phase of a program can be measured. False if the kernel refused.
inline bool reset_peak_rss() {
    std::ofstream out("/proc/self/clear_refs");
    out << "5";
    out.flush();
    return static_cast<bool>(out);
}

inline double gib(int64_t bytes) {
    return double(bytes) / double(int64_t(1) << 30);
}
inline double mib(int64_t bytes) {
    return double(bytes) / double(int64_t(1) << 20);
}

/// Every image of a source held in memory as float RGB, so that codecs that read the source in
/// several passes measure their own work rather than the source's (a synthetic source renders
/// every image again on each read).
class MemorySource final : public BtfSource {
  public:
    /// Reads all images of `source` (in parallel).
    explicit MemorySource(const BtfSource& source)
        : m_width(source.width()),
          m_height(source.height()),
          m_sampling(source.sampling()),
          m_info(source.info()) {
        m_info.note = "in memory: " + m_info.note;
        const int64_t values = int64_t(m_width) * m_height * 3;
        m_images.resize(m_sampling.num_images());
        parallel_for(0, int64_t(m_images.size()), [&](int64_t i) {
            Image image;
            source.read_image(int(i / num_lights()), int(i % num_lights()), image);
            m_images[i].assign(image.data(), image.data() + values);
        });
    }

    int width() const override { return m_width; }
    int height() const override { return m_height; }
    const Sampling& sampling() const override { return m_sampling; }
    const SourceInfo& info() const override { return m_info; }
    void read_image(int view, int light, Image& out) const override {
        if (view < 0 || view >= num_views() || light < 0 || light >= num_lights())
            fail("memory source: no image (view {}, light {})", view, light);
        out.reshape(m_width, m_height, 3);
        const std::vector<float>& v = m_images[size_t(view) * num_lights() + light];
        std::copy(v.begin(), v.end(), out.data());
    }
    /// The pixels of one image: width × height × 3 floats, row-major.
    const float* pixels(int view, int light) const {
        return m_images[size_t(view) * num_lights() + light].data();
    }

  private:
    int m_width, m_height;
    Sampling m_sampling;
    SourceInfo m_info;
    std::vector<std::vector<float>> m_images;
};

/// A randomized SVD configuration as the factorization benchmarks take it on their command line:
/// method:q[:block[:oversampling]], e.g. krylov:2:37 or subspace:3::5; -1 where not written.
struct SvdConfig {
    factor::SvdMethod method = factor::SvdMethod::kSubspace;
    int power_iterations = -1, block = -1, oversampling = -1;
};

inline SvdConfig parse_svd_config(const std::string& spec) {
    std::vector<std::string> f;
    for (size_t b = 0, e; b <= spec.size(); b = e + 1) {
        e = std::min(spec.find(':', b), spec.size());
        f.push_back(spec.substr(b, e - b));
    }
    if ((f[0] != "krylov" && f[0] != "subspace") || f.size() > 4)
        fail("{}: expected krylov|subspace:q[:block[:oversampling]]", spec);
    SvdConfig out;
    out.method = f[0] == "krylov" ? factor::SvdMethod::kBlockKrylov : factor::SvdMethod::kSubspace;
    int* fields[] = {&out.power_iterations, &out.block, &out.oversampling};
    for (size_t i = 1; i < f.size(); ++i)
        if (!f[i].empty()) *fields[i - 1] = std::stoi(f[i]);
    return out;
}

}  // namespace btf::bench
