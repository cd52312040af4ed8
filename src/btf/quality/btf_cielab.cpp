// SPDX-License-Identifier: MIT
// BTF-CIELab (Guthe et al. 2009, §3–4). The pipeline for one spatial resolution r_s:
//
//   pass 1 (per view, lights in parallel): read the reference and the test image, convert both to
//     lαβ, filter every plane spatially with each Gaussian of the CSF in the Fourier domain, and
//     store the seven filtered channels of both BTFs quantized, in texel tiles;
//   pass 2 (per texel tile, in parallel): decode the tile, filter it over the view directions and
//     then over the light directions with each Gaussian for every angular speed ω of this r_s,
//     recombine the Gaussians into lαβ, convert to CIELab and accumulate the CIEDE2000 statistics.
//
// Pass 1 packs two real planes into the real and imaginary part of one complex FFT (α and β; and
// two achromatic Gaussians of l on the way back): the Gaussian transfer functions are real and
// even, so filtering keeps both parts apart. The reference and the test go through the same
// arithmetic separately, so identical inputs give exactly zero.

#include "btf/quality/btf_cielab.h"

#include <fcntl.h>
#include <kiss_fftnd.h>
#include <tbb/enumerable_thread_specific.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstring>
#include <map>
#include <memory>
#include <numbers>
#include <system_error>

#include "btf/codecs/perceptual/csf.h"
#include "btf/core/color.h"
#include "btf/core/image.h"
#include "btf/io/source.h"
#include "btf/quality/batch_colour.h"
#include "btf/quality/metrics.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::quality {

namespace {

// ---- Table 1 of the paper: the spatio-angular CSF as sums of 6-D Gaussians ------------------
// Weight, spatial standard deviation σ (degrees of visual angle) and temporal δ (seconds), of
// e(x, t) ∝ exp(−x²/σ² − t²/δ²), each normalized to unit integral.
struct Gaussian {
    double weight, sigma, delta;
};
constexpr std::array<Gaussian, 3> kAchromatic{
    {{2.05962, 0.058406, 0.025135}, {1.29338, 0.038015, 0.054688}, {-2.35300, 0.140856, 0.090229}}};
constexpr std::array<Gaussian, 2> kChromatic{
    {{0.67965, 0.096652, 0.069195}, {0.32035, 0.054198, 0.031830}}};

// The seven filtered channels: l with the three achromatic Gaussians, α and β with the two
// chromatic ones.
constexpr int kChannels = 7;
constexpr int kPlaneOf[kChannels] = {0, 0, 0, 1, 1, 2, 2};
const Gaussian& gaussian_of(int channel) {
    return channel < 3 ? kAchromatic[size_t(channel)] : kChromatic[size_t((channel - 3) % 2)];
}

// ---- FFT plans: kissfft configurations hold scratch memory, so each thread owns its own ------
struct FftPlans {
    std::map<std::tuple<int, int, bool>, std::unique_ptr<void, void (*)(void*)>> plans;
    kiss_fftnd_cfg get(int width, int height, bool inverse) {
        auto key = std::make_tuple(width, height, inverse);
        auto it = plans.find(key);
        if (it == plans.end()) {
            const int dims[2] = {height, width};
            kiss_fftnd_cfg cfg = kiss_fftnd_alloc(dims, 2, inverse ? 1 : 0, nullptr, nullptr);
            if (!cfg) fail("BTF-CIELab: cannot allocate a {}×{} FFT", width, height);
            it = plans.emplace(key, std::unique_ptr<void, void (*)(void*)>(cfg, &kiss_fft_free))
                     .first;
        }
        return static_cast<kiss_fftnd_cfg>(it->second.get());
    }
};

// Frequency of DFT bin k of n samples, in cycles per sample.
double bin_frequency(int k, int n) {
    return (k <= n / 2 ? k : k - n) / double(n);
}

// Transfer function of one spatial Gaussian exp(−x²/σ²) (unit integral, σ in degrees) at view
// `view` for a resolution of `resolution` texels per degree. The projection compresses the
// texture by cos θ along the view azimuth φ, so along that axis the kernel covers 1/cos θ times
// more texels; its Fourier transform is exp(−π² s² (f∥²/cos²θ + f⊥²)) with s = σ·r_s texels.
void spatial_transfer(const Gaussian& g, double resolution, const Direction& view, int width,
                      int height, std::vector<float>& out) {
    const double s = g.sigma * resolution;
    const double cos_theta = std::max(std::cos(view.theta), 1e-3);
    const double cp = std::cos(view.phi), sp = std::sin(view.phi);
    const double k = std::numbers::pi * std::numbers::pi * s * s;
    out.resize(size_t(width) * size_t(height));
    for (int y = 0; y < height; ++y) {
        const double fy = bin_frequency(y, height);
        for (int x = 0; x < width; ++x) {
            const double fx = bin_frequency(x, width);
            const double along = (fx * cp + fy * sp) / cos_theta;
            const double across = -fx * sp + fy * cp;
            out[size_t(y) * size_t(width) + size_t(x)] =
                float(std::exp(-k * (along * along + across * across)));
        }
    }
}

// One angular filter: row-normalized Gaussian weights exp(−d²/(δω)²) between the directions of a
// set (d the great-circle angle in degrees), stored sparsely so that a narrow kernel costs
// nothing; a row whose only weight is its own direction is the identity and is skipped.
struct AngularFilter {
    bool identity = true;
    std::vector<std::vector<std::pair<int, float>>> rows;
    /// The same weights as a dense matrix when rows have more than six non-zero weights on
    /// average: then a matrix product (Eigen's blocked GEMM) is faster than streaming the block
    /// once per weight (measured on the 81-direction sets).
    Eigen::MatrixXf dense;
};

AngularFilter angular_filter(const DirectionSet& set, double width_deg) {
    // The same discrete Gaussian as the perceptual codec's CSF (great-circle angle, rows
    // normalized to 1); weights below 1e-6 of a row's diagonal are dropped.
    const Eigen::MatrixXd kernel = perceptual::angular_kernel(set, width_deg);
    AngularFilter f;
    const int n = set.size();
    f.rows.resize(size_t(n));
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            if (kernel(i, j) < 1e-6 * kernel(i, i)) continue;
            f.rows[size_t(i)].emplace_back(j, float(kernel(i, j)));
            if (j != i) f.identity = false;
        }
    size_t nonzero = 0;
    for (const auto& row : f.rows) nonzero += row.size();
    if (nonzero > 6 * size_t(n)) {
        f.dense = Eigen::MatrixXf::Zero(n, n);
        for (int i = 0; i < n; ++i)
            for (const auto& [j, w] : f.rows[size_t(i)]) f.dense(i, j) = w;
    }
    return f;
}

// ---- scratch space: memory when it fits the budget, otherwise an unlinked temporary file -------
class Scratch {
  public:
    Scratch(int64_t bytes, int64_t& memory_budget, const std::filesystem::path& folder)
        : m_bytes(bytes) {
        if (bytes <= memory_budget) {
            m_memory.resize(size_t(bytes));
            memory_budget -= bytes;
            return;
        }
        const std::filesystem::path dir =
            folder.empty() ? std::filesystem::temp_directory_path() : folder;
        std::string name = (dir / "btf-cielab-XXXXXX").string();
        m_fd = ::mkstemp(name.data());
        if (m_fd < 0)
            fail("{}: cannot create the BTF-CIELab scratch file: {}", dir.string(),
                 std::strerror(errno));
        ::unlink(name.c_str());  // gone from the folder now; freed when closed, even on a crash
    }
    ~Scratch() {
        if (m_fd >= 0) ::close(m_fd);
    }
    Scratch(const Scratch&) = delete;
    Scratch& operator=(const Scratch&) = delete;

    int64_t bytes() const { return m_bytes; }
    bool spilled() const { return m_fd >= 0; }

    void write(int64_t offset, const uint8_t* data, int64_t size) {
        if (!spilled()) {
            std::memcpy(m_memory.data() + offset, data, size_t(size));
            return;
        }
        io(true, const_cast<uint8_t*>(data), size, offset);
    }
    void read(int64_t offset, uint8_t* data, int64_t size) const {
        if (!spilled()) {
            std::memcpy(data, m_memory.data() + offset, size_t(size));
            return;
        }
        io(false, data, size, offset);
    }

  private:
    void io(bool write, uint8_t* data, int64_t size, int64_t offset) const {
        while (size > 0) {
            const ssize_t n = write ? ::pwrite(m_fd, data, size_t(size), offset)
                                    : ::pread(m_fd, data, size_t(size), offset);
            if (n <= 0) {
                if (n < 0 && errno == EINTR) continue;
                fail("BTF-CIELab scratch file: {} failed: {}", write ? "write" : "read",
                     n < 0 ? std::strerror(errno) : "unexpected end of file");
            }
            data += n, size -= n, offset += n;
        }
    }

    int64_t m_bytes;
    std::vector<uint8_t> m_memory;
    int m_fd = -1;
};

// Bytes of one quantized record of `values` values: offset, step, the values, padded to 8 bytes.
int64_t record_size(int64_t values, int bits) {
    return (8 + values * (bits / 8) + 7) / 8 * 8;
}

// Quantizes `n` values (padding the record to the tile size with the last value).
void encode_record(const float* values, int n, int tile, int bits, uint8_t* record) {
    float lo = values[0], hi = values[0];
    for (int i = 1; i < n; ++i) lo = std::min(lo, values[i]), hi = std::max(hi, values[i]);
    const float levels = bits == 16 ? 65535.0f : 255.0f;
    const float step = hi > lo ? (hi - lo) / levels : 0.0f;
    const float inv = step > 0 ? 1.0f / step : 0.0f;
    std::memcpy(record, &lo, 4);
    std::memcpy(record + 4, &step, 4);
    if (bits == 16) {
        auto* q = reinterpret_cast<uint16_t*>(record + 8);
        for (int i = 0; i < tile; ++i)
            q[i] = uint16_t((values[std::min(i, n - 1)] - lo) * inv + 0.5f);  // ≥ 0: rounds
    } else {
        uint8_t* q = record + 8;
        for (int i = 0; i < tile; ++i)
            q[i] = uint8_t((values[std::min(i, n - 1)] - lo) * inv + 0.5f);
    }
}

void decode_record(const uint8_t* record, int n, int bits, float* out) {
    float lo, step;
    std::memcpy(&lo, record, 4);
    std::memcpy(&step, record + 4, 4);
    if (bits == 16) {
        const auto* q = reinterpret_cast<const uint16_t*>(record + 8);
        for (int i = 0; i < n; ++i) out[i] = lo + step * float(q[i]);
    } else {
        const uint8_t* q = record + 8;
        for (int i = 0; i < n; ++i) out[i] = lo + step * float(q[i]);
    }
}

// Float arrays as Eigen vectors: Eigen vectorizes their arithmetic explicitly, which GCC's -O2
// leaves scalar for plain loops over several arrays.
Eigen::Map<Eigen::VectorXf> vec(float* data, int64_t n) {
    return {data, Eigen::Index(n)};
}
Eigen::Map<const Eigen::VectorXf> vec(const float* data, int64_t n) {
    return {data, Eigen::Index(n)};
}

// ---- statistics --------------------------------------------------------------------------------
struct Sums {
    double weight = 0, sum = 0, sum_sq = 0;
    void add(const Sums& o) { weight += o.weight, sum += o.sum, sum_sq += o.sum_sq; }
};

BtfCielabValue finish(const ViewingCondition& condition, const Sums& s) {
    BtfCielabValue v;
    v.condition = condition;
    if (s.weight > 0) {
        v.mean = s.sum / s.weight;
        v.rms = std::sqrt(s.sum_sq / s.weight);
        v.stddev = std::sqrt(std::max(0.0, v.rms * v.rms - v.mean * v.mean));
    }
    return v;
}

class Evaluator {
  public:
    Evaluator(const BtfSource& reference, const BtfSource& test, const BtfCielabOptions& options,
              Progress& progress)
        : m_ref(reference),
          m_test(test),
          m_options(options),
          m_progress(progress),
          m_width(reference.width()),
          m_height(reference.height()),
          m_views(reference.num_views()),
          m_lights(reference.num_lights()) {
        m_texels = int64_t(m_width) * m_height;
        m_budget = options.memory_bytes;
        m_tile = int(std::min<int64_t>(256, m_texels));
        m_tiles = (m_texels + m_tile - 1) / m_tile;
    }

    /// Evaluates every condition; those with the same resolution share one spatial pass.
    std::vector<BtfCielabValue> evaluate(const std::vector<ViewingCondition>& conditions) {
        std::map<double, std::vector<size_t>> by_resolution;
        for (size_t i = 0; i < conditions.size(); ++i)
            by_resolution[conditions[i].resolution].push_back(i);
        std::vector<BtfCielabValue> out(conditions.size());
        for (const auto& [resolution, indices] : by_resolution) {
            std::vector<double> speeds;
            for (size_t i : indices) speeds.push_back(conditions[i].angular_speed);
            const std::vector<Sums> sums = run(resolution, speeds);
            for (size_t k = 0; k < indices.size(); ++k)
                out[indices[k]] = finish(conditions[indices[k]], sums[k]);
        }
        return out;
    }

    int64_t store_bytes() const { return m_store_bytes; }
    bool spilled() const { return m_spilled; }

  private:
    // One spatial pass at `resolution`, then the angular passes for every speed.
    std::vector<Sums> run(double resolution, const std::vector<double>& speeds) {
        if (!m_input) convert_inputs();
        int64_t budget = m_budget;  // what the input store left; the filtered store is freed after
        Scratch store(m_tiles * tile_bytes(), budget, m_options.scratch);
        m_store_bytes = std::max(m_store_bytes, m_input->bytes() + store.bytes());
        m_spilled = m_spilled || store.spilled() || m_input->spilled();
        spatial_pass(resolution, store);
        return angular_pass(store, speeds);
    }

    // Filtered store layout: tile-major, then view, light, BTF (0 = reference, 1 = test),
    // channel; each record holds one tile's texels of one channel of one image.
    int64_t filtered_record() const { return record_size(m_tile, m_options.bits); }
    int64_t view_bytes() const { return int64_t(m_lights) * 2 * kChannels * filtered_record(); }
    int64_t tile_bytes() const { return int64_t(m_views) * view_bytes(); }
    // Input store layout: view, light, BTF, plane (l, α, β); one record per whole image plane.
    int64_t input_record() const { return record_size(m_texels, m_options.bits); }
    int64_t input_view_bytes() const { return int64_t(m_lights) * 2 * 3 * input_record(); }

    // Reads both BTFs once and stores their lαβ planes quantized like the filtered channels
    // (the paper's §4.1: the input of every later pass), so that a package is decoded once and
    // not once per spatial resolution.
    void convert_inputs() {
        m_input = std::make_unique<Scratch>(int64_t(m_views) * input_view_bytes(), m_budget,
                                            m_options.scratch);
        std::vector<uint8_t> records(static_cast<size_t>(input_view_bytes()));
        struct Work {
            Image image;
            std::vector<float> planes;
        };
        tbb::enumerable_thread_specific<Work> work;
        m_progress.begin("BTF-CIELab: reading and converting to cone responses", uint64_t(m_views));
        for (int view = 0; view < m_views; ++view) {
            parallel_for(0, int64_t(m_lights) * 2, [&](int64_t job) {
                m_progress.poll();
                const int light = int(job / 2), b = int(job % 2);
                Work& w = work.local();
                (b == 0 ? m_ref : m_test).read_image(view, light, w.image);
                w.planes.resize(size_t(3 * m_texels));
                for (int64_t t = 0; t < m_texels; ++t) {
                    const float* c = w.image.data() + t * w.image.channels();
                    const auto o = rgb_to_opponent({c[0], c[1], c[2]});
                    for (int k = 0; k < 3; ++k) w.planes[size_t(k * m_texels + t)] = o[size_t(k)];
                }
                for (int k = 0; k < 3; ++k)
                    encode_record(
                        w.planes.data() + k * m_texels, int(m_texels), int(m_texels),
                        m_options.bits,
                        records.data() + ((int64_t(light) * 2 + b) * 3 + k) * input_record());
            });
            m_input->write(view * input_view_bytes(), records.data(), input_view_bytes());
            m_progress.advance();
        }
        m_progress.finish();
    }

    void spatial_pass(double resolution, Scratch& store) {
        const int64_t texels = m_texels;
        const int64_t record = filtered_record();
        // One view's records, tile-major: [tile][light][btf][channel].
        const int64_t per_tile = view_bytes();
        std::vector<uint8_t> view_records(size_t(per_tile * m_tiles));
        std::vector<uint8_t> view_input(static_cast<size_t>(input_view_bytes()));
        tbb::enumerable_thread_specific<FftPlans> plans;
        struct Work {
            std::vector<float> opponent;  // l, α, β
            std::vector<std::complex<float>> planes[2], spectra[2], product, filtered;
            std::vector<float> values;
        };
        tbb::enumerable_thread_specific<Work> scratch;
        std::vector<std::vector<float>> transfer(kChannels);

        m_progress.begin(fmt::format("BTF-CIELab r_s {:.3g} px/°: spatial filtering", resolution),
                         uint64_t(m_views));
        for (int view = 0; view < m_views; ++view) {
            for (int c = 0; c < kChannels; ++c)
                spatial_transfer(gaussian_of(c), resolution, m_ref.sampling().views[view], m_width,
                                 m_height, transfer[size_t(c)]);
            m_input->read(view * input_view_bytes(), view_input.data(), input_view_bytes());
            parallel_for(0, m_lights, [&](int64_t light) {
                m_progress.poll();
                Work& s = scratch.local();
                FftPlans& p = plans.local();
                kiss_fftnd_cfg forward = p.get(m_width, m_height, false);
                kiss_fftnd_cfg backward = p.get(m_width, m_height, true);
                auto fft = [](kiss_fftnd_cfg cfg, std::vector<std::complex<float>>& in,
                              std::vector<std::complex<float>>& out) {
                    kiss_fftnd(cfg, reinterpret_cast<kiss_fft_cpx*>(in.data()),
                               reinterpret_cast<kiss_fft_cpx*>(out.data()));
                };
                for (auto* v : {&s.planes[0], &s.planes[1], &s.spectra[0], &s.spectra[1],
                                &s.product, &s.filtered})
                    v->resize(size_t(texels));
                s.values.resize(size_t(texels) * kChannels);
                const float norm = 1.0f / float(texels);
                s.opponent.resize(size_t(3 * texels));
                for (int b = 0; b < 2; ++b) {
                    for (int k = 0; k < 3; ++k)
                        decode_record(
                            view_input.data() + ((light * 2 + b) * 3 + k) * input_record(),
                            int(texels), m_options.bits, s.opponent.data() + k * texels);
                    const float* o = s.opponent.data();
                    for (int64_t t = 0; t < texels; ++t) {
                        s.planes[0][size_t(t)] = {o[t], 0.0f};
                        s.planes[1][size_t(t)] = {o[texels + t], o[2 * texels + t]};
                    }
                    fft(forward, s.planes[0], s.spectra[0]);
                    fft(forward, s.planes[1], s.spectra[1]);
                    // Each inverse transform yields two real channels (real and imaginary part).
                    for (const auto& [spectrum, c0, c1] :
                         {std::tuple{0, 0, 1}, {0, 2, -1}, {1, 3, 5}, {1, 4, 6}}) {
                        const auto& in = s.spectra[size_t(spectrum)];
                        const auto& h0 = transfer[size_t(c0)];
                        if (spectrum == 0 && c1 >= 0) {
                            // Achromatic: H_c0·L̂ + i·H_c1·L̂ gives filt_c0(l) + i·filt_c1(l).
                            const auto& h1 = transfer[size_t(c1)];
                            for (int64_t t = 0; t < texels; ++t)
                                s.product[size_t(t)] =
                                    in[size_t(t)] *
                                    std::complex<float>(h0[size_t(t)] * norm, h1[size_t(t)] * norm);
                        } else {
                            // H·(α̂ + iβ̂) gives filt(α) + i·filt(β); H·L̂ alone gives filt(l).
                            for (int64_t t = 0; t < texels; ++t)
                                s.product[size_t(t)] = in[size_t(t)] * (h0[size_t(t)] * norm);
                        }
                        fft(backward, s.product, s.filtered);
                        float* out0 = s.values.data() + int64_t(c0) * texels;
                        for (int64_t t = 0; t < texels; ++t) out0[t] = s.filtered[size_t(t)].real();
                        if (c1 >= 0) {
                            float* out1 = s.values.data() + int64_t(c1) * texels;
                            for (int64_t t = 0; t < texels; ++t)
                                out1[t] = s.filtered[size_t(t)].imag();
                        }
                    }
                    for (int64_t tile = 0; tile < m_tiles; ++tile) {
                        const int64_t first = tile * m_tile;
                        const int n = int(std::min<int64_t>(m_tile, texels - first));
                        for (int c = 0; c < kChannels; ++c) {
                            uint8_t* rec = view_records.data() + tile * per_tile +
                                           ((light * 2 + b) * kChannels + c) * record;
                            encode_record(s.values.data() + c * texels + first, n, m_tile,
                                          m_options.bits, rec);
                        }
                    }
                }
            });
            for (int64_t tile = 0; tile < m_tiles; ++tile)
                store.write(tile * tile_bytes() + view * view_bytes(),
                            view_records.data() + tile * per_tile, per_tile);
            m_progress.advance();
        }
        m_progress.finish();
    }

    std::vector<Sums> angular_pass(const Scratch& store, const std::vector<double>& speeds) {
        // Filters per speed and Gaussian: views and lights, each Gaussian's width δ·ω degrees.
        struct Filters {
            std::array<AngularFilter, kChannels> views, lights;
        };
        std::vector<Filters> filters(speeds.size());
        for (size_t s = 0; s < speeds.size(); ++s)
            for (int c = 0; c < kChannels; ++c) {
                const double width = gaussian_of(c).delta * speeds[s];
                filters[s].views[size_t(c)] = angular_filter(m_ref.sampling().views, width);
                filters[s].lights[size_t(c)] = angular_filter(m_ref.sampling().lights, width);
            }
        // Speeds so slow that no filter reaches a neighbouring direction all give the spatially
        // filtered BTF itself: they are evaluated once (the first such speed) and share the sums.
        std::vector<size_t> same_as(speeds.size());
        for (size_t s = 0; s < speeds.size(); ++s) {
            same_as[s] = s;
            bool identity = true;
            for (int c = 0; c < kChannels; ++c)
                identity = identity && filters[s].views[size_t(c)].identity &&
                           filters[s].lights[size_t(c)].identity;
            if (!identity) continue;
            for (size_t t = 0; t < s; ++t)
                if (same_as[t] == t && filters[t].views[0].identity) {
                    bool all = true;
                    for (int c = 0; c < kChannels; ++c)
                        all = all && filters[t].views[size_t(c)].identity &&
                              filters[t].lights[size_t(c)].identity;
                    if (all) {
                        same_as[s] = t;
                        break;
                    }
                }
        }
        std::vector<double> view_weight(static_cast<size_t>(m_views));
        for (int v = 0; v < m_views; ++v)
            view_weight[size_t(v)] = std::max(0.0, std::cos(m_ref.sampling().views[v].theta));

        const int64_t images = int64_t(m_views) * m_lights;
        struct Work {
            std::vector<uint8_t> bytes;
            std::vector<float> decoded;  // [btf][channel][view][light][texel]
            std::vector<float> a, b;     // filtering buffers of one channel
            std::vector<float> opp;      // [btf][plane][view][light][texel]
            std::vector<float> lab;      // CIELab of both BTFs and ΔE00 for one view
        };
        tbb::enumerable_thread_specific<Work> work;
        std::vector<std::vector<Sums>> tile_sums(size_t(m_tiles), std::vector<Sums>(speeds.size()));
        m_progress.begin("BTF-CIELab: angular filtering and CIEDE2000", uint64_t(m_tiles));
        parallel_for(0, m_tiles, [&](int64_t tile) {
            m_progress.poll();
            Work& w = work.local();
            const int64_t first = tile * m_tile;
            const int n = int(std::min<int64_t>(m_tile, m_texels - first));
            const int64_t block = images * n;  // one channel of one BTF
            w.bytes.resize(size_t(tile_bytes()));
            store.read(tile * tile_bytes(), w.bytes.data(), tile_bytes());
            w.decoded.resize(size_t(2 * kChannels * block));
            for (int64_t image = 0; image < images; ++image)
                for (int b = 0; b < 2; ++b)
                    for (int c = 0; c < kChannels; ++c)
                        decode_record(
                            w.bytes.data() + ((image * 2 + b) * kChannels + c) * filtered_record(),
                            n, m_options.bits,
                            w.decoded.data() + (b * kChannels + c) * block + image * n);
            w.a.resize(size_t(block));
            w.b.resize(size_t(block));
            w.opp.resize(size_t(2 * 3 * block));
            for (size_t s = 0; s < speeds.size(); ++s) {
                if (same_as[s] != s) continue;
                std::fill(w.opp.begin(), w.opp.end(), 0.0f);
                for (int b = 0; b < 2; ++b)
                    for (int c = 0; c < kChannels; ++c) {
                        const float* x = w.decoded.data() + (b * kChannels + c) * block;
                        const float* y = filter_views(filters[s].views[size_t(c)], x, w.a, n);
                        y = filter_lights(filters[s].lights[size_t(c)], y, w.b, n);
                        float* acc = w.opp.data() + (b * 3 + kPlaneOf[c]) * block;
                        const float weight = float(gaussian_of(c).weight);
                        vec(acc, block) += weight * vec(y, block);
                    }
                Sums& sums = tile_sums[size_t(tile)][s];
                // lαβ → CIELab for both BTFs, then CIEDE2000, one view at a time.
                const int64_t row = int64_t(m_lights) * n;
                w.lab.resize(size_t(7 * row));
                const float* o = w.opp.data();
                for (int v = 0; v < m_views; ++v) {
                    const int64_t off = int64_t(v) * row;
                    float* lab = w.lab.data();
                    opponent_to_lab({o + off, o + block + off, o + 2 * block + off},
                                    {lab, lab + row, lab + 2 * row}, row);
                    opponent_to_lab({o + 3 * block + off, o + 4 * block + off, o + 5 * block + off},
                                    {lab + 3 * row, lab + 4 * row, lab + 5 * row}, row);
                    float* de = lab + 6 * row;
                    ciede2000(Planes{lab, lab + row, lab + 2 * row},
                              Planes{lab + 3 * row, lab + 4 * row, lab + 5 * row}, de, row);
                    double sum = 0, sum_sq = 0;
                    for (int64_t i = 0; i < row; ++i) sum += de[i], sum_sq += double(de[i]) * de[i];
                    const double vw = view_weight[size_t(v)];
                    sums.weight += vw * double(row);
                    sums.sum += vw * sum;
                    sums.sum_sq += vw * sum_sq;
                }
            }
            m_progress.advance();
        });
        m_progress.finish();
        // Reduce in tile order: the result does not depend on how tiles were scheduled.
        std::vector<Sums> total(speeds.size());
        for (const auto& per_tile : tile_sums)
            for (size_t s = 0; s < speeds.size(); ++s) total[s].add(per_tile[same_as[s]]);
        return total;
    }

    // y[v][l][t] = Σ_v' f[v][v'] x[v'][l][t]; returns x itself for an identity filter.
    const float* filter_views(const AngularFilter& f, const float* x, std::vector<float>& out,
                              int n) const {
        if (f.identity) return x;
        const int64_t row = int64_t(m_lights) * n;
        if (f.dense.size() > 0) {
            using Rows = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
            Eigen::Map<const Rows> in(x, m_views, row);
            Eigen::Map<Rows> y(out.data(), m_views, row);
            y.noalias() = f.dense * in;
            return out.data();
        }
        for (int v = 0; v < m_views; ++v) {
            float* y = out.data() + v * row;
            std::fill(y, y + row, 0.0f);
            for (const auto& [j, wj] : f.rows[size_t(v)]) {
                const float* src = x + j * row;
                vec(y, row) += wj * vec(src, row);
            }
        }
        return out.data();
    }
    // y[v][l][t] = Σ_l' f[l][l'] x[v][l'][t].
    const float* filter_lights(const AngularFilter& f, const float* x, std::vector<float>& out,
                               int n) const {
        if (f.identity) return x;
        if (f.dense.size() > 0) {
            using Rows = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
            for (int v = 0; v < m_views; ++v) {
                const int64_t offset = int64_t(v) * m_lights * n;
                Eigen::Map<const Rows> in(x + offset, m_lights, n);
                Eigen::Map<Rows> y(out.data() + offset, m_lights, n);
                y.noalias() = f.dense * in;
            }
            return out.data();
        }
        for (int v = 0; v < m_views; ++v)
            for (int l = 0; l < m_lights; ++l) {
                float* y = out.data() + (int64_t(v) * m_lights + l) * n;
                std::fill(y, y + n, 0.0f);
                for (const auto& [j, wj] : f.rows[size_t(l)]) {
                    const float* src = x + (int64_t(v) * m_lights + j) * n;
                    vec(y, n) += wj * vec(src, n);
                }
            }
        return out.data();
    }

    const BtfSource& m_ref;
    const BtfSource& m_test;
    const BtfCielabOptions& m_options;
    Progress& m_progress;
    int m_width, m_height, m_views, m_lights;
    int64_t m_texels = 0, m_tiles = 0;
    int m_tile = 0;
    int64_t m_store_bytes = 0;
    bool m_spilled = false;
    int64_t m_budget = 0;              // memory left for stores
    std::unique_ptr<Scratch> m_input;  // the lαβ planes of both BTFs
};

constexpr double kSpeedRange[2] = {10, 1000};
constexpr double kResolutionRange[2] = {2, 100};

double log_lerp(const double (&range)[2], double t) {
    return range[0] * std::pow(range[1] / range[0], t);
}

void check_condition(const ViewingCondition& c) {
    if (!(c.angular_speed >= kSpeedRange[0] && c.angular_speed <= kSpeedRange[1]))
        fail("BTF-CIELab: angular speed {} °/s is outside [10, 1000]", c.angular_speed);
    if (!(c.resolution >= kResolutionRange[0] && c.resolution <= kResolutionRange[1]))
        fail("BTF-CIELab: spatial resolution {} px/° is outside [2, 100]", c.resolution);
}

}  // namespace

BtfCielabResult btf_cielab(const BtfSource& reference, const BtfSource& test,
                           const BtfCielabOptions& options, Progress& progress) {
    check_comparable(reference, test);
    if (options.bits != 8 && options.bits != 16)
        fail("BTF-CIELab: {} bits per stored value: use 8 or 16", options.bits);
    const auto start = std::chrono::steady_clock::now();

    std::vector<ViewingCondition> conditions = options.conditions;
    if (conditions.empty()) {
        if (options.grid < 1 || options.grid > 20)
            fail("BTF-CIELab: a viewing-condition grid of {} × {}: use 1 to 20", options.grid,
                 options.grid);
        const int g = options.grid;
        for (int i = 0; i < g; ++i)
            for (int j = 0; j < g; ++j) {
                const double ti = g == 1 ? 0.5 : double(i) / (g - 1);
                const double tj = g == 1 ? 0.5 : double(j) / (g - 1);
                conditions.push_back({log_lerp(kSpeedRange, ti), log_lerp(kResolutionRange, tj)});
            }
    }
    for (const auto& c : conditions) check_condition(c);

    Evaluator evaluator(reference, test, options, progress);
    BtfCielabResult result;
    result.values = evaluator.evaluate(conditions);
    auto worst_of = [&] {
        int worst = 0;
        for (size_t i = 1; i < result.values.size(); ++i)
            if (result.values[i].rms > result.values[size_t(worst)].rms) worst = int(i);
        return worst;
    };
    result.worst = worst_of();

    if (options.search) {
        // Compass search for the condition of largest RMS difference, in log10 of both
        // parameters, from the grid's worst point: try the four neighbours at the current step,
        // move to the best if it is worse than the current point, otherwise halve the step.
        // (The paper uses Levenberg–Marquardt on the same objective; both stop at a stationary
        // point, and the compass search needs no derivatives of a noisy function.)
        const double ls[2] = {std::log10(kSpeedRange[0]), std::log10(kSpeedRange[1])};
        const double lr[2] = {std::log10(kResolutionRange[0]), std::log10(kResolutionRange[1])};
        double step = 0.25 * (ls[1] - ls[0]) / std::max(1, options.grid - 1);
        while (step > 0.02) {
            const ViewingCondition at = result.headline().condition;
            const double s0 = std::log10(at.angular_speed), r0 = std::log10(at.resolution);
            std::vector<ViewingCondition> next;
            for (const auto& [ds, dr] :
                 {std::pair{step, 0.0}, {-step, 0.0}, {0.0, step}, {0.0, -step}}) {
                const double s = std::clamp(s0 + ds, ls[0], ls[1]);
                const double r = std::clamp(r0 + dr, lr[0], lr[1]);
                if (s == s0 && r == r0) continue;
                next.push_back({std::pow(10.0, s), std::pow(10.0, r)});
            }
            const auto values = evaluator.evaluate(next);
            const double before = result.headline().rms;
            result.values.insert(result.values.end(), values.begin(), values.end());
            result.worst = worst_of();
            if (result.headline().rms <= before) step *= 0.5;
        }
        result.searched = true;
    }
    result.store_bytes = evaluator.store_bytes();
    result.spilled = evaluator.spilled();
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

}  // namespace btf::quality
