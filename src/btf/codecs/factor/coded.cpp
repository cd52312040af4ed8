// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/coded.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include <fmt/format.h>
#include <zstd.h>
#include <Eigen/Core>

#include "btf/util/dct8.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/range_coder.h"

namespace btf::factor::coded {

namespace {

constexpr uint8_t kPlain = 0, kDctImage = 1;
constexpr size_t kHead = 12;  // format, a stride, b kind, b stride, step a, step b
constexpr int kMaxStride = 64;
// Quantized values are kept within ±2³¹ (a step far below a value's size would need more).
constexpr double kMaxCode = 2147483647.0;

double rms(ConstColumn c) {
    double sum = 0;
    for (int64_t i = 0; i < c.n; ++i) sum += double(c.data[i * c.stride]) * c.data[i * c.stride];
    return c.n > 0 ? std::sqrt(sum / double(c.n)) : 0.0;
}

// The step for one side: Δ over the RMS of the other side (1 where that is 0: the product is 0
// whatever this side holds).
float side_step(double step, double other_rms) {
    const double s = step / other_rms;
    return std::isfinite(s) && s > 0 && s < 1e30 ? float(s) : 1.0f;
}

// Decoded values are rounded to half floats: the evaluator then keeps the rows as halves, as for
// f16 packages (half the memory per query; FactorMaterial).
float as_half(double v) {
    return from_half(to_half(float(v)));
}

int64_t rounded(double v) {
    return int64_t(std::clamp(std::nearbyint(v), -kMaxCode, kMaxCode));
}

// The integers of a section: format 1 reads zig-zag varints, format 2 the range coder's
// integer model (util/range_coder.h), whose context says which stream a value is in.
enum Stream : int {
    kAngular = 0,        // a: differences along the rows (or the middle channel's)
    kAngularChroma = 1,  // a, channel prediction: the outer channels' differences to the middle
    kTexels = 2,         // b without a neighbourhood (lpca's clusters)
    kDc = 3,             // b: DC differences along the blocks
    kBands = 4,          // b: 4 + the band's group (1…8: the zig-zag diagonals, 36…63 last)
    kAngularDc = 13,     // a as images of its planes (kDctPlanes): DC differences
    kAngularBands = 14,  // … and 14 + the band's group
    kStreams = kAngularBands + 9
};

int band_group(int k) {
    // The zig-zag index where diagonal d (d = 1…7) starts: 1, 3, 6, 10, 15, 21, 28; the lower
    // triangle (36…63) is group 8.
    int group = 1;
    for (const int start : {3, 6, 10, 15, 21, 28, 36})
        if (k >= start) ++group;
    return group;
}

struct VarintReader {
    const uint8_t* p;
    const uint8_t* end;
    std::string_view what;
    int64_t get(int) { return dct8::get_varint(p, end, what); }
};

struct RangeReader {
    range::Decoder& coder;
    range::IntegerModel& model;
    int64_t get(int stream) { return model.get(coder, stream); }
};

// The writers of the two formats: put(stream, v), then finish() for the payload.
struct VarintWriter {
    std::vector<uint8_t> out;
    void put(int, int64_t v) { dct8::put_varint(out, v); }
    std::vector<uint8_t> finish() { return std::move(out); }
};

struct RangeWriter {
    range::Encoder coder;
    range::IntegerModel model{kStreams};
    void put(int stream, int64_t v) { model.put(coder, stream, v); }
    std::vector<uint8_t> finish() { return coder.finish(); }
};

// Wrapping addition: a hostile difference must not overflow (the value is then checked for being
// finite like every decoded factor).
int64_t plus(int64_t a, int64_t b) {
    return int64_t(uint64_t(a) + uint64_t(b));
}

// Prediction kNeighbours (format 2, a's rows laid out as AngularRows): the values of each
// (view, light) pair as planes (3 channels: the middle channel, then the outer ones' offsets to
// it; otherwise each channel), each predicted by the floor of the mean of the same plane at the
// previous light of the view and at the same light of the previous view (the one of them there
// is, at a view's first light or in the first view; 0 for the first pair): the angular factors
// are smooth over both directions.
constexpr int kNeighbours = 128;

int64_t minus(int64_t a, int64_t b) {
    return int64_t(uint64_t(a) - uint64_t(b));
}

int64_t floor_mean(int64_t x, int64_t y) {
    return (x >> 1) + (y >> 1) + (x & y & 1);
}

bool neighbours_fit(AngularRows rows, int64_t n) {
    return rows.lights > 0 && (rows.channels == 1 || rows.channels == 3) &&
           n % (rows.lights * rows.channels) == 0;
}

int64_t plane_of(const int64_t* codes, int channels, int64_t pair, int j) {
    const int64_t* q = codes + pair * channels;
    if (channels != 3) return q[j];
    return j == 0 ? q[1] : minus(q[j == 1 ? 0 : 2], q[1]);
}

int64_t neighbour_prediction(const int64_t* codes, AngularRows rows, int64_t pair, int j) {
    const bool left = pair % rows.lights > 0, up = pair >= rows.lights;
    if (left && up)
        return floor_mean(plane_of(codes, rows.channels, pair - 1, j),
                          plane_of(codes, rows.channels, pair - rows.lights, j));
    if (left) return plane_of(codes, rows.channels, pair - 1, j);
    if (up) return plane_of(codes, rows.channels, pair - rows.lights, j);
    return 0;
}

int plane_stream(int channels, int j) {
    return channels == 3 && j > 0 ? kAngularChroma : kAngular;
}

// Uniform rounding, as differences to the code `stride` values before; stride 0 (3 channels per
// row): the middle channel as differences along the rows, the outer ones as differences of
// their offsets to the middle one, written middle first; kNeighbours: see above.
template <class Writer>
void put_plain(Writer& out, ConstColumn c, float step, int stride, int stream,
               AngularRows rows = {}) {
    std::vector<int64_t> codes(size_t(c.n));
    for (int64_t i = 0; i < c.n; ++i)
        codes[size_t(i)] = rounded(double(c.data[i * c.stride]) / step);
    if (stride == kNeighbours) {
        for (int64_t pair = 0; pair < c.n / rows.channels; ++pair)
            for (int j = 0; j < rows.channels; ++j)
                out.put(plane_stream(rows.channels, j),
                        minus(plane_of(codes.data(), rows.channels, pair, j),
                              neighbour_prediction(codes.data(), rows, pair, j)));
        return;
    }
    if (stride == 0) {
        for (int64_t i = 0; i < c.n; i += 3) {
            const int64_t* q = &codes[size_t(i)];
            const int64_t* before = i >= 3 ? q - 3 : nullptr;
            out.put(kAngular, q[1] - (before ? before[1] : 0));
            for (const int ch : {0, 2})
                out.put(kAngularChroma, (q[ch] - q[1]) - (before ? before[ch] - before[1] : 0));
        }
        return;
    }
    for (int64_t i = 0; i < c.n; ++i)
        out.put(stream, codes[size_t(i)] - (i >= stride ? codes[size_t(i - stride)] : 0));
}

template <class Reader>
void get_plain(Reader& in, Column c, float step, int stride, int stream, AngularRows rows = {}) {
    std::vector<int64_t> codes(size_t(c.n));
    if (stride == kNeighbours) {
        int64_t planes[3];
        for (int64_t pair = 0; pair < c.n / rows.channels; ++pair) {
            for (int j = 0; j < rows.channels; ++j)
                planes[j] = plus(in.get(plane_stream(rows.channels, j)),
                                 neighbour_prediction(codes.data(), rows, pair, j));
            int64_t* q = &codes[size_t(pair * rows.channels)];
            if (rows.channels == 3) {
                q[1] = planes[0];
                q[0] = plus(planes[1], q[1]);
                q[2] = plus(planes[2], q[1]);
            } else {
                q[0] = planes[0];
            }
        }
    } else if (stride == 0) {
        for (int64_t i = 0; i < c.n; i += 3) {
            int64_t* q = &codes[size_t(i)];
            const int64_t* before = i >= 3 ? q - 3 : nullptr;
            q[1] = plus(in.get(kAngular), before ? before[1] : 0);
            for (const int ch : {0, 2})
                q[ch] = plus(plus(in.get(kAngularChroma),
                                  before ? int64_t(uint64_t(before[ch]) - uint64_t(before[1])) : 0),
                             q[1]);
        }
    } else {
        for (int64_t i = 0; i < c.n; ++i)
            codes[size_t(i)] = plus(in.get(stream), i >= stride ? codes[size_t(i - stride)] : 0);
    }
    for (int64_t i = 0; i < c.n; ++i)
        c.data[i * c.stride] = as_half(double(codes[size_t(i)]) * step);
}

int blocks_along(int size) {
    return (size + 7) / 8;
}

template <class Writer>
void put_image(Writer& out, ConstColumn c, Image image, float step, int dc_stream = kDc,
               bool mirror = false) {
    // The blocks past the edge hold the image extended periodically (b: the evaluator wraps), or
    // mirrored (a's images of directions, which do not wrap); the reader drops them either way.
    auto extend = [mirror](int i, int size) {
        if (i < size) return i;
        return mirror ? std::max(0, 2 * size - 1 - i) : i % size;
    };
    const int bw = blocks_along(image.width), bh = blocks_along(image.height);
    const size_t blocks = size_t(bw) * size_t(bh);
    std::vector<int64_t> codes(blocks * 64);
    double in[64], coef[64];
    for (int by = 0; by < bh; ++by)
        for (int bx = 0; bx < bw; ++bx) {
            for (int r = 0; r < 8; ++r)
                for (int n = 0; n < 8; ++n) {
                    const int y = extend(by * 8 + r, image.height),
                              x = extend(bx * 8 + n, image.width);
                    in[r * 8 + n] = c.data[(int64_t(y) * image.width + x) * c.stride];
                }
            dct8::forward(in, coef);
            int64_t* q = &codes[(size_t(by) * size_t(bw) + size_t(bx)) * 64];
            for (int k = 0; k < 64; ++k) {
                const double v = coef[dct8::kZigZag[k]] / step;
                const double m = std::floor(std::abs(v) + 1.0 / 3.0);
                q[k] = int64_t(std::min(m, kMaxCode)) * (v < 0 ? -1 : 1);
            }
        }
    for (int k = 0; k < 64; ++k) {
        int64_t previous = 0;
        const int stream = k == 0 ? dc_stream : dc_stream + 1 + band_group(k);
        for (size_t b = 0; b < blocks; ++b) {
            const int64_t v = codes[b * 64 + size_t(k)];
            out.put(stream, k == 0 ? v - previous : v);
            previous = v;
        }
    }
}

template <class Reader>
void get_image(Reader& in, Column c, Image image, float step, int dc_stream = kDc) {
    const int bw = blocks_along(image.width), bh = blocks_along(image.height);
    const size_t blocks = size_t(bw) * size_t(bh);
    std::vector<int64_t> codes(blocks * 64);
    for (int k = 0; k < 64; ++k) {
        int64_t previous = 0;
        const int stream = k == 0 ? dc_stream : dc_stream + 1 + band_group(k);
        for (size_t b = 0; b < blocks; ++b) {
            const int64_t d = in.get(stream);
            const int64_t v = k == 0 ? plus(d, previous) : d;
            codes[b * 64 + size_t(k)] = v;
            previous = v;
        }
    }
    double coef[64], out[64];
    for (int by = 0; by < bh; ++by)
        for (int bx = 0; bx < bw; ++bx) {
            const int64_t* q = &codes[(size_t(by) * size_t(bw) + size_t(bx)) * 64];
            for (int k = 0; k < 64; ++k) coef[dct8::kZigZag[k]] = double(q[k]) * step;
            dct8::inverse(coef, out);
            for (int r = 0; r < 8; ++r)
                for (int n = 0; n < 8; ++n) {
                    const int y = by * 8 + r, x = bx * 8 + n;
                    if (y < image.height && x < image.width)
                        c.data[(int64_t(y) * image.width + x) * c.stride] = as_half(out[r * 8 + n]);
                }
        }
}

// Prediction kDctPlanes (format 2, a's rows laid out as AngularRows): each plane of a (as for
// kNeighbours: the middle channel and the outer ones' offsets to it, or the one channel) as an
// image of views × lights, coded like b's images (8 × 8 DCT blocks, dead-zone quantization) but
// mirrored past its edges (directions do not wrap), in streams of its own.
constexpr int kDctPlanes = 129;

Image angular_image(AngularRows rows, int64_t n) {
    return {int(rows.lights), int(n / rows.channels / rows.lights)};
}

template <class Writer>
void put_angular_image(Writer& out, ConstColumn c, float step, AngularRows rows) {
    const int64_t pairs = c.n / rows.channels;
    std::vector<float> plane(static_cast<size_t>(pairs));
    for (int j = 0; j < rows.channels; ++j) {
        for (int64_t p = 0; p < pairs; ++p) {
            const float* v = c.data + p * rows.channels * c.stride;
            plane[size_t(p)] = rows.channels != 3 ? v[0]
                               : j == 0           ? v[c.stride]
                                                  : v[(j == 1 ? 0 : 2) * c.stride] - v[c.stride];
        }
        put_image(out, {plane.data(), pairs, 1}, angular_image(rows, c.n), step, kAngularDc, true);
    }
}

template <class Reader>
void get_angular_image(Reader& in, Column c, float step, AngularRows rows) {
    const int64_t pairs = c.n / rows.channels;
    std::vector<float> planes(static_cast<size_t>(pairs * rows.channels));
    for (int j = 0; j < rows.channels; ++j)
        get_image(in, {planes.data() + j * pairs, pairs, 1}, angular_image(rows, c.n), step,
                  kAngularDc);
    for (int64_t p = 0; p < pairs; ++p) {
        float* v = c.data + p * rows.channels * c.stride;
        if (rows.channels != 3) {
            v[0] = planes[size_t(p)];
            continue;
        }
        const float middle = planes[size_t(p)];
        v[c.stride] = middle;
        v[0] = as_half(double(planes[size_t(pairs + p)]) + middle);
        v[2 * c.stride] = as_half(double(planes[size_t(2 * pairs + p)]) + middle);
    }
}

template <class Writer>
void put_angular(Writer& out, ConstColumn c, float step, int prediction, AngularRows rows) {
    if (prediction == kDctPlanes)
        put_angular_image(out, c, step, rows);
    else
        put_plain(out, c, step, prediction, kAngular, rows);
}

template <class Reader>
void get_angular(Reader& in, Column c, float step, int prediction, AngularRows rows) {
    if (prediction == kDctPlanes)
        get_angular_image(in, c, step, rows);
    else
        get_plain(in, c, step, prediction, kAngular, rows);
}

bool is_image(Image image, int64_t n) {
    return image.width > 0 && image.height > 0 && int64_t(image.width) * image.height == n;
}

}  // namespace

double value_step(double quality, double rms) {
    return std::exp2(-quality / 10.0) * rms;
}

namespace {

// The section's head: format, a's prediction, b's kind and prediction, the two steps.
void put_head(std::vector<uint8_t>& out, uint8_t format, int a_prediction, bool dct, float step_a,
              float step_b) {
    const uint8_t head[4] = {format, uint8_t(a_prediction), dct ? kDctImage : kPlain,
                             uint8_t(dct ? 0 : 1)};
    out.insert(out.end(), head, head + 4);
    const float steps[2] = {step_a, step_b};
    const auto* bytes = reinterpret_cast<const uint8_t*>(steps);
    out.insert(out.end(), bytes, bytes + 8);
}

// A section in one format: a's prediction the one of `predictions` of least cost (below), the
// head, then the payload.
template <class Writer>
std::vector<uint8_t> coded_as(uint8_t format, const std::vector<int>& predictions, ConstColumn a,
                              ConstColumn b, Image image, float step_a, float step_b,
                              AngularRows rows) {
    // The prediction of least cost J = D + λ R (D: a's squared error, R: its bits). The exact
    // predictions all round a alike, so among them the shortest wins; the images of directions
    // (kDctPlanes) drop, through their dead zone, detail that costs more than it is worth. λ is
    // the slope of a uniform quantizer's D(R), ln 2 / 6 · step², at the balanced step Δ / rms(b)
    // (b's side; a's step is κ times that), expressed in a's units: ln 2 / 6 · (s_a / κ)².
    double best_cost = 0;
    int best = predictions.front();
    const double balanced = double(step_a) / kAngularStepScale;
    const double lambda = std::log(2.0) / 6.0 * balanced * balanced;
    // The rounded predictions' error, the same for each of them.
    double rounding = 0;
    for (int64_t i = 0; i < a.n; ++i) {
        const double v = a.data[i * a.stride];
        const double e = v - as_half(double(rounded(v / step_a)) * step_a);
        rounding += e * e;
    }
    for (const int prediction : predictions) {
        Writer trial;
        put_angular(trial, a, step_a, prediction, rows);
        const std::vector<uint8_t> bytes = trial.finish();
        double distortion = rounding;
        if constexpr (std::is_same_v<Writer, RangeWriter>) {
            if (prediction == kDctPlanes) {  // a as decoded: through the images' dead zone
                std::vector<float> decoded(static_cast<size_t>(a.n));
                range::Decoder coder(bytes.data(), bytes.size(), "(trial)");
                range::IntegerModel model(kStreams);
                RangeReader in{coder, model};
                get_angular(in, {decoded.data(), a.n, 1}, step_a, prediction, rows);
                distortion = 0;
                for (int64_t i = 0; i < a.n; ++i) {
                    const double e = double(a.data[i * a.stride]) - decoded[size_t(i)];
                    distortion += e * e;
                }
            }
        }
        const double cost = distortion + lambda * 8.0 * double(bytes.size());
        if (prediction == predictions.front() || cost < best_cost) {
            best_cost = cost;
            best = prediction;
        }
    }
    const bool dct = is_image(image, b.n);
    std::vector<uint8_t> out;
    put_head(out, format, best, dct, step_a, step_b);
    Writer writer;
    put_angular(writer, a, step_a, best, rows);
    if (dct)
        put_image(writer, b, image, step_b);
    else
        put_plain(writer, b, step_b, 1, kTexels);
    const std::vector<uint8_t> payload = writer.finish();
    out.insert(out.end(), payload.begin(), payload.end());
    return out;
}

size_t zstd_size(const std::vector<uint8_t>& bytes) {
    std::vector<uint8_t> frame(ZSTD_compressBound(bytes.size()));
    const size_t n =
        ZSTD_compress(frame.data(), frame.size(), bytes.data(), bytes.size(), kZstdLevelForChoice);
    return ZSTD_isError(n) ? bytes.size() : std::min(n, bytes.size());
}

// The smaller of the two formats once the container has compressed them (the range coder's
// adaptive models miss the repeated runs that zstd's matches find in some factors: brushed
// metal's angular factors are a fifth shorter as varints under zstd).
void put_coded(std::vector<uint8_t>& out, ConstColumn a, ConstColumn b, Image image, float step_a,
               float step_b, AngularRows rows) {
    // Format 2 may predict rgb rows by channel (0) and by neighbouring directions; format 1 has
    // distances only.
    std::vector<int> predictions = {1, 2, 3, 4, 6};
    const std::vector<uint8_t> varints =
        coded_as<VarintWriter>(kVarintFormat, predictions, a, b, image, step_a, step_b, rows);
    if (a.n % 3 == 0) predictions.insert(predictions.begin(), 0);
    if (neighbours_fit(rows, a.n)) {
        predictions.push_back(kNeighbours);
        predictions.push_back(kDctPlanes);
    }
    const std::vector<uint8_t> ranged =
        coded_as<RangeWriter>(kFormat, predictions, a, b, image, step_a, step_b, rows);
    const std::vector<uint8_t>& best = zstd_size(varints) < ranged.size() ? varints : ranged;
    out.insert(out.end(), best.begin(), best.end());
}

// The values a stands for: itself, or at an angular level its up-sampling U a.
std::vector<float> upsampled(const std::vector<float>& a, const AngularResampler* up) {
    if (!up) return a;
    const Eigen::VectorXd full = up->upsample(
        Eigen::Map<const Eigen::VectorXf>(a.data(), Eigen::Index(a.size())).cast<double>().eval());
    std::vector<float> out(size_t(full.size()));
    for (Eigen::Index i = 0; i < full.size(); ++i) out[size_t(i)] = float(full(i));
    return out;
}

// The mean weight of a stored a value in the values it stands for: ‖U‖²_F over U's columns (1
// without an angular level).
double stored_weight(const AngularResampler* up) {
    if (!up) return 1.0;
    return up->up_views().squaredNorm() * up->up_lights().squaredNorm() /
           double(up->up_views().cols() * up->up_lights().cols());
}

double dot(ConstColumn x, const std::vector<float>& y) {
    double sum = 0;
    for (int64_t i = 0; i < x.n; ++i) sum += double(x.data[i * x.stride]) * y[size_t(i)];
    return sum;
}

double squared(const std::vector<float>& x) {
    double sum = 0;
    for (const float v : x) sum += double(v) * v;
    return sum;
}

}  // namespace

void put_component(std::vector<uint8_t>& out, ConstColumn a, ConstColumn b, Image image,
                   double step, const AngularResampler* up, AngularRows rows) {
    std::vector<float> a_values(size_t(a.n));
    for (int64_t i = 0; i < a.n; ++i) a_values[size_t(i)] = a.data[i * a.stride];
    const std::vector<float> a_full = upsampled(a_values, up);
    const ConstColumn full{a_full.data(), int64_t(a_full.size()), 1};
    const float step_a = side_step(kAngularStepScale * step, rms(b) * std::sqrt(stored_weight(up)));
    const float step_b = side_step(step, rms(full));
    std::vector<uint8_t> coded;
    put_coded(coded, a, b, image, step_a, step_b, rows);
    // The component as decoded, â b̂ᵀ, lowers the error of the values it is added to only if
    // ‖a bᵀ − â b̂ᵀ‖² < ‖a bᵀ‖², i.e. 2 (a·â)(b·b̂) > ‖â‖²‖b̂‖² (the rest of the residual is
    // orthogonal to a); otherwise it is stored as zeros, so that a longer prefix is never worse.
    // At an angular level both a are up-sampled: U â is in U's range, to which the original full
    // a differs from U a by an orthogonal residual (a was fitted by least squares), so a·U â =
    // U a · U â.
    std::vector<float> a_hat(size_t(a.n)), b_hat(size_t(b.n));
    get_component(coded.data(), coded.size(), {a_hat.data(), a.n, 1}, {b_hat.data(), b.n, 1}, image,
                  "(encoding)", rows);
    const std::vector<float> a_hat_full = upsampled(a_hat, up);
    if (!(2 * dot(full, a_hat_full) * dot(b, b_hat) > squared(a_hat_full) * squared(b_hat))) {
        const std::vector<float> zero_a(size_t(a.n), 0.0f), zero_b(size_t(b.n), 0.0f);
        coded.clear();
        put_coded(coded, {zero_a.data(), a.n, 1}, {zero_b.data(), b.n, 1}, image, step_a, step_b,
                  rows);
    }
    out.insert(out.end(), coded.begin(), coded.end());
}

void get_component(const uint8_t* data, size_t size, Column a, Column b, Image image,
                   std::string_view name, AngularRows rows) {
    const std::string what = fmt::format("section '{}'", name);
    if (size < kHead) fail("{}: {} bytes, shorter than a coded component's head", what, size);
    const int format = data[0];
    if (format != kFormat && format != kVarintFormat)
        fail("{}: unknown coded format {}", what, format);
    const int a_stride = data[1], kind = data[2], b_stride = data[3];
    float steps[2];
    std::memcpy(steps, data + 4, 8);
    // Predictions 0 (channels, for rows of 3 channels) and kNeighbours (for the rows' layout)
    // are format 2's.
    if (a_stride == kDctPlanes) {
        if (format == kVarintFormat) fail("{}: a as images of directions in format 1", what);
        if (!neighbours_fit(rows, a.n))
            fail(
                "{}: a as images of directions, but the factor's rows are not laid out by "
                "directions",
                what);
    } else if (a_stride == kNeighbours) {
        if (format == kVarintFormat)
            fail("{}: prediction by neighbouring directions in format 1", what);
        if (!neighbours_fit(rows, a.n))
            fail(
                "{}: prediction by neighbouring directions, but the factor's rows are not laid "
                "out by directions",
                what);
    } else if (a_stride > kMaxStride ||
               (a_stride == 0 && (format == kVarintFormat || a.n % 3 != 0))) {
        fail("{}: prediction distance {}", what, a_stride);
    }
    if (kind != kPlain && kind != kDctImage) fail("{}: unknown texel coding {}", what, kind);
    if (kind == kDctImage && !is_image(image, b.n))
        fail("{}: DCT-coded texels, but the block's texels are not an image", what);
    if (kind == kPlain && (b_stride < 1 || b_stride > kMaxStride))
        fail("{}: prediction distance {}", what, b_stride);
    for (const float s : steps)
        if (!(s > 0) || !std::isfinite(s)) fail("{}: quantization step {}", what, s);
    auto factors = [&](auto& in) {
        get_angular(in, a, steps[0], a_stride, rows);
        if (kind == kDctImage)
            get_image(in, b, image, steps[1]);
        else
            get_plain(in, b, steps[1], b_stride, kTexels);
    };
    size_t left = 0;
    if (format == kVarintFormat) {
        VarintReader in{data + kHead, data + size, what};
        factors(in);
        left = size_t(in.end - in.p);
    } else {
        range::Decoder coder(data + kHead, size - kHead, what);
        range::IntegerModel model(kStreams);
        RangeReader in{coder, model};
        factors(in);
        left = coder.remaining();
    }
    if (left != 0) fail("{}: {} bytes after the coded factors", what, left);
}

}  // namespace btf::factor::coded
