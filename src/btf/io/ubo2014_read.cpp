// SPDX-License-Identifier: MIT
// Reading Bonn UBO2014 .btf files (FORMATS.md, "Bonn UBO2014 .btf", items 1–7).
//
// The file is parsed in two passes. The first walks every header and size field, seeking over the
// matrices, and checks each declared size against the file length, the sampling and sane limits;
// the second allocates and reads the matrices. So a corrupt size field fails with a message
// naming the byte offset before anything large is allocated.

#include <Eigen/Core>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>

#include "btf/io/ubo2014.h"
#include "btf/util/error.h"
#include "btf/util/limits.h"

namespace btf::ubo2014 {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little,
              "the UBO2014 reader assumes a little-endian host");

namespace {

// Sane limits: far above any measured BTF, low enough that products stay in int64.
constexpr uint32_t kMaxDirections = 1u << 16;
constexpr uint32_t kMaxSide = 1u << 20;
constexpr uint64_t kMaxTexels = uint64_t(1) << 32;
constexpr uint32_t kMaxChannels = 1024;
constexpr uint32_t kMaxComponents = 1u << 20;
constexpr uint32_t kMaxMetaVersion = 1000;
// version 1: size, version, 3 × char[80], ppmm, rgb scale factor
constexpr uint32_t kMetaV1Bytes = 4 + 4 + 3 * 80 + 4 + 12;

struct Signature {
    const char* text;
    const char* what;
    bool supported;
    Body body;
};

// Longest first, so that a prefix match picks "!DFMF08FCR" before "!DFMF08FC".
constexpr Signature kSignatures[] = {
    {"!BDIF06R2!", "uncompressed chunked BDI", false, Body::kDfmf},
    {"!DFMF08FCR", "DFMF with rotations", true, Body::kDfmf},
    {"!FMF12FCER", "FMF with rotations", true, Body::kFmf},
    {"!DFMF08FC", "DFMF", true, Body::kDfmf},
    {"!FMF12FCE", "FMF", true, Body::kFmf},
    {"!FMF06FCR", "older FMF with rotations", false, Body::kFmf},
    {"!PVF06FCR", "per-view PCA with rotations", false, Body::kFmf},
    {"!FMF06FC", "older FMF", false, Body::kFmf},
    {"!PVF06FC", "per-view PCA", false, Body::kFmf},
};
constexpr size_t kMaxSignatureLength = 10;

// Sequential little-endian reads from a file of known length; every read checks what is left.
class FileReader {
  public:
    explicit FileReader(const fs::path& path) : m_name(path.string()) {
        std::error_code ec;
        if (!fs::is_regular_file(path, ec)) fail("{}: no such file", m_name);
        m_size = fs::file_size(path, ec);
        if (ec) fail("{}: cannot determine file size: {}", m_name, ec.message());
        m_in.open(path, std::ios::binary);
        if (!m_in) fail("{}: cannot open for reading", m_name);
    }

    const std::string& name() const { return m_name; }
    uint64_t size() const { return m_size; }
    uint64_t pos() const { return m_pos; }
    uint64_t remaining() const { return m_size - m_pos; }

    // Fails unless `bytes` more bytes exist; `what` names the field.
    void need(uint64_t bytes, std::string_view what) const {
        if (bytes > remaining())
            fail("{}: byte {}: {} needs {} bytes but the file ends after {}", m_name, m_pos, what,
                 bytes, remaining());
    }

    void read_bytes(void* out, uint64_t bytes, std::string_view what) {
        need(bytes, what);
        m_in.read(static_cast<char*>(out), static_cast<std::streamsize>(bytes));
        if (!m_in) fail("{}: byte {}: read error in {}", m_name, m_pos, what);
        m_pos += bytes;
    }

    template <typename T>
    T get(std::string_view what) {
        T value;
        read_bytes(&value, sizeof(T), what);
        return value;
    }

    std::string get_string(uint64_t length, std::string_view what) {
        need(length, what);
        std::string s(length, '\0');
        read_bytes(s.data(), length, what);
        return s;
    }

    void seek(uint64_t pos) {
        m_in.clear();
        m_in.seekg(static_cast<std::streamoff>(pos));
        if (!m_in) fail("{}: byte {}: seek failed", m_name, pos);
        m_pos = pos;
    }

    template <typename... Args>
    [[noreturn]] void fail_here(fmt::format_string<Args...> format, Args&&... args) const {
        fail("{}: byte {}: {}", m_name, m_pos, fmt::format(format, std::forward<Args>(args)...));
    }
    template <typename... Args>
    [[noreturn]] void fail_at(uint64_t pos, fmt::format_string<Args...> format,
                              Args&&... args) const {
        fail("{}: byte {}: {}", m_name, pos, fmt::format(format, std::forward<Args>(args)...));
    }

  private:
    std::string m_name;
    std::ifstream m_in;
    uint64_t m_size = 0;
    uint64_t m_pos = 0;
};

std::string printable(const std::string& bytes) {
    std::string out;
    for (unsigned char c : bytes)
        out += (c >= 32 && c < 127) ? std::string(1, char(c)) : fmt::format("\\x{:02x}", c);
    return out;
}

// Reads the file's first bytes and picks the signature. A signature without R followed by a meta
// size whose low byte is 'R' (0x52) reads like the R variant; the meta header that follows decides.
const Signature& identify(FileReader& in) {
    std::string head(std::min<uint64_t>(in.size(), kMaxSignatureLength + 8), '\0');
    in.read_bytes(head.data(), head.size(), "signature");
    const Signature* best = nullptr;
    for (const Signature& s : kSignatures)
        if (head.compare(0, std::strlen(s.text), s.text) == 0) {
            best = &s;
            break;
        }
    if (!best)
        fail(
            "{}: not a Bonn UBO .btf file: it starts with '{}', which is none of the signatures "
            "!DFMF08FC, !FMF12FCE (with optional R), !FMF06FC, !PVF06FC, !BDIF06R2!",
            in.name(), printable(head.substr(0, kMaxSignatureLength)));
    const size_t len = std::strlen(best->text);
    if (best->supported && best->text[len - 1] == 'R') {
        auto plausible_meta = [&](size_t at) {
            if (in.size() < at + 8) return false;
            uint32_t size = 0, version = 0;
            if (head.size() >= at + 8) {
                std::memcpy(&size, head.data() + at, 4);
                std::memcpy(&version, head.data() + at + 4, 4);
            }
            return version >= 1 && version <= kMaxMetaVersion && size >= kMetaV1Bytes &&
                   size <= in.size() - at;
        };
        if (!plausible_meta(len) && plausible_meta(len - 1)) {
            for (const Signature& s : kSignatures)
                if (std::strlen(s.text) == len - 1 && head.compare(0, len - 1, s.text) == 0)
                    best = &s;
        }
    }
    if (!best->supported)
        fail(
            "{}: unsupported UBO .btf signature '{}' ({}); btfkit reads !DFMF08FC and !FMF12FCE, "
            "each with or without a trailing R",
            in.name(), best->text, best->what);
    in.seek(std::strlen(best->text));
    return *best;
}

std::string fixed_string(const char (&raw)[80]) {
    return std::string(raw, strnlen(raw, 80));
}

Meta read_meta(FileReader& in) {
    Meta meta;
    const uint64_t start = in.pos();
    const auto size = in.get<uint32_t>("meta block size");
    meta.version = in.get<uint32_t>("meta block version");
    if (meta.version < 1 || meta.version > kMaxMetaVersion)
        in.fail_at(start + 4, "meta block version {} is not a UBO meta version (1..4)",
                   meta.version);
    if (size < kMetaV1Bytes)
        in.fail_at(start, "meta block declares {} bytes, fewer than the {} of its fixed fields",
                   size, kMetaV1Bytes);
    if (size > in.size() - start)
        in.fail_at(start, "meta block declares {} bytes but the file ends after {}", size,
                   in.size() - start);
    const uint64_t end = start + size;
    // Reads inside the block report "beyond the declared size" rather than "file ends".
    auto need_in_block = [&](uint64_t bytes, std::string_view what) {
        if (in.pos() + bytes > end)
            in.fail_here("meta block declares {} bytes but its {} reaches beyond them", size, what);
    };
    char raw[80];
    need_in_block(3 * 80 + 16, "fixed fields");
    in.read_bytes(raw, 80, "measurement setup");
    meta.measurement_setup = fixed_string(raw);
    in.read_bytes(raw, 80, "image sensor");
    meta.image_sensor = fixed_string(raw);
    in.read_bytes(raw, 80, "light source");
    meta.light_source = fixed_string(raw);
    meta.ppmm = in.get<float>("ppmm");
    for (float& f : meta.rgb_scale_factor) f = in.get<float>("rgb scale factor");
    if (meta.version > 1) {
        need_in_block(4, "cosine flag");
        meta.cosine_flag = in.get<uint32_t>("cosine flag") != 0;
    }
    if (meta.version > 2) {
        need_in_block(4, "XML length");
        const auto length = in.get<uint32_t>("XML length");
        need_in_block(length, fmt::format("XML string of {} bytes", length));
        meta.xml = in.get_string(length, "XML string");
    }
    if (meta.version > 3) {
        need_in_block(4, "channel count");
        const uint64_t at = in.pos();
        const auto channels = in.get<uint32_t>("channel count");
        if (channels == 0 || channels > kMaxChannels)
            in.fail_at(at, "meta block declares {} colour channels (expected 1..{})", channels,
                       kMaxChannels);
        for (uint32_t c = 0; c < channels; ++c) {
            need_in_block(4, fmt::format("name length of channel {}", c));
            const auto length = in.get<uint32_t>("channel name length");
            need_in_block(length, fmt::format("name of channel {} ({} bytes)", c, length));
            meta.channel_names.push_back(in.get_string(length, "channel name"));
        }
    }
    if (in.pos() != end) {
        if (meta.version <= 4)
            in.fail_at(start,
                       "meta block declares {} bytes but its version {} fields take {} (the size "
                       "field is inconsistent)",
                       size, meta.version, in.pos() - start);
        // A newer version appends fields btfkit does not know: skip them.
        meta.skipped_bytes = static_cast<uint32_t>(end - in.pos());
        in.seek(end);
    }
    return meta;
}

bool check_direction(float theta, float phi) {
    return std::isfinite(theta) && std::isfinite(phi) && theta >= -1e-3f &&
           theta <= float(kPi / 2 + 1e-3);
}

Direction to_direction(float theta, float phi) {
    double p = std::fmod(double(phi), 2 * kPi);
    if (p < 0) p += 2 * kPi;
    if (p >= 2 * kPi) p = 0;
    return {std::clamp(double(theta), 0.0, kPi / 2), p};
}

bool same_angle(float a, float b) {
    double d = std::fmod(std::abs(double(a) - double(b)), 2 * kPi);
    return std::min(d, 2 * kPi - d) <= 1e-5;
}

DirectionSet named_set(std::vector<Direction> dirs, const std::string& fallback) {
    DirectionSet set(fallback, std::move(dirs));
    if (set.same_directions(DirectionSet::dome151()))
        return DirectionSet("dome151", set.directions());
    return set;
}

Sampling read_sampling(FileReader& in, const std::string& stem) {
    const uint64_t at = in.pos();
    const auto num_views = in.get<uint32_t>("view count");
    if (num_views == 0 || num_views > kMaxDirections)
        in.fail_at(at, "declares {} views (expected 1..{})", num_views, kMaxDirections);
    // Each view takes at least 12 bytes (θ, φ, light count).
    in.need(uint64_t(num_views) * 12, fmt::format("directions of {} views", num_views));
    std::vector<Direction> views;
    std::vector<float> first_lights;  // θ, φ pairs of view 0
    views.reserve(num_views);
    for (uint32_t v = 0; v < num_views; ++v) {
        const uint64_t view_at = in.pos();
        const auto theta = in.get<float>("view direction");
        const auto phi = in.get<float>("view direction");
        if (!check_direction(theta, phi))
            in.fail_at(view_at,
                       "view {} has direction θ = {} rad, φ = {} rad (not on the upper "
                       "hemisphere)",
                       v, theta, phi);
        views.push_back(to_direction(theta, phi));
        const uint64_t count_at = in.pos();
        const auto num_lights = in.get<uint32_t>("light count");
        if (num_lights == 0 || num_lights > kMaxDirections)
            in.fail_at(count_at, "view {} declares {} lights (expected 1..{})", v, num_lights,
                       kMaxDirections);
        if (v > 0 && num_lights * 2 != first_lights.size())
            in.fail_at(count_at,
                       "view {} declares {} lights but view 0 declared {}; btfkit needs the same "
                       "light set for all views",
                       v, num_lights, first_lights.size() / 2);
        const uint64_t bytes = uint64_t(num_lights) * 8;
        if (bytes > in.remaining())
            in.fail_here(
                "view {} of {} declares {} light directions ({} bytes) but the file ends "
                "after {} bytes",
                v, num_views, num_lights, bytes, in.remaining());
        std::vector<float> lights(size_t(num_lights) * 2);
        in.read_bytes(lights.data(), bytes, "light directions");
        for (uint32_t l = 0; l < num_lights; ++l)
            if (!check_direction(lights[2 * l], lights[2 * l + 1]))
                in.fail_at(count_at + 4 + 8 * l,
                           "light {} of view {} has direction θ = {} rad, φ = {} rad (not on the "
                           "upper hemisphere)",
                           l, v, lights[2 * l], lights[2 * l + 1]);
        if (v == 0) {
            first_lights = std::move(lights);
            continue;
        }
        for (uint32_t l = 0; l < num_lights; ++l)
            if (std::abs(lights[2 * l] - first_lights[2 * l]) > 1e-5f ||
                !same_angle(lights[2 * l + 1], first_lights[2 * l + 1]))
                in.fail_at(count_at + 4 + 8 * l,
                           "view {} carries a different light set than view 0 (light {}: θ = {}, "
                           "φ = {} rad vs θ = {}, φ = {} rad); btfkit needs the same light set "
                           "for all views",
                           v, l, lights[2 * l], lights[2 * l + 1], first_lights[2 * l],
                           first_lights[2 * l + 1]);
    }
    std::vector<Direction> lights;
    for (size_t l = 0; l < first_lights.size() / 2; ++l)
        lights.push_back(to_direction(first_lights[2 * l], first_lights[2 * l + 1]));
    return {named_set(std::move(views), stem + "-views"),
            named_set(std::move(lights), stem + "-lights")};
}

// Where one factor's matrices lie in the file (from the first pass).
struct FactorPlan {
    std::string label;  // "channel 1" or "FMF"
    int scalar_size = 4;
    uint64_t k = 0, rows = 0, cols = 0;
    uint64_t s_at = 0, u_at = 0, sxv_at = 0;
};

void check_scalar_size(FileReader& in, uint64_t at, int scalar_size, const std::string& label) {
    if (scalar_size != 2 && scalar_size != 4 && scalar_size != 8)
        in.fail_at(at, "{} has scalar size {} (expected 2 = half, 4 = float32, 8 = float64)", label,
                   scalar_size);
}

// Checks K, rows, cols against the expectations, then locates S, U, SxV and seeks past them.
FactorPlan plan_matrices(FileReader& in, uint64_t header_at, FactorPlan plan,
                         uint64_t expected_rows, const std::string& rows_meaning,
                         uint64_t expected_cols) {
    if (plan.rows != expected_rows)
        in.fail_at(header_at, "{} declares {} rows but {} = {}", plan.label, plan.rows,
                   rows_meaning, expected_rows);
    if (plan.cols != expected_cols)
        in.fail_at(header_at, "{} declares {} columns but width × height = {}", plan.label,
                   plan.cols, expected_cols);
    if (plan.k > plan.rows || plan.k > plan.cols || plan.k > kMaxComponents)
        in.fail_at(header_at,
                   "{} declares K = {} components, more than min(rows, columns) = {} allows",
                   plan.label, plan.k, std::min(plan.rows, plan.cols));
    const uint64_t ss = plan.scalar_size;
    plan.s_at = in.pos();
    if (plan.k * ss > in.remaining())
        in.fail_here("S of {} declares {} values but the file ends after {}", plan.label, plan.k,
                     in.remaining() / ss);
    plan.u_at = plan.s_at + plan.k * ss;
    const uint64_t row_bytes = plan.k * ss;
    auto check_matrix = [&](uint64_t at, uint64_t rows, const char* name) {
        const uint64_t left = in.size() - at;
        if (rows * row_bytes > left)
            in.fail_at(at, "{} matrix of {} declares {}×{} rows×cols but file ends after {} rows",
                       name, plan.label, rows, plan.k, row_bytes ? left / row_bytes : 0);
    };
    check_matrix(plan.u_at, plan.rows, "U");
    plan.sxv_at = plan.u_at + plan.rows * row_bytes;
    check_matrix(plan.sxv_at, plan.cols, "SxV");
    in.seek(plan.sxv_at + plan.cols * row_bytes);
    return plan;
}

// Reads `count` scalars of `scalar_size` bytes starting at the reader's position into `out`,
// rejecting NaN and Inf with the byte offset of the bad value.
void read_scalars(FileReader& in, int scalar_size, float* out, uint64_t count,
                  const std::string& name, uint64_t row_length, Progress& progress) {
    constexpr uint64_t kChunk = uint64_t(1) << 20;
    std::vector<unsigned char> buffer;
    uint64_t done = 0;
    while (done < count) {
        const uint64_t n = std::min(kChunk, count - done);
        const uint64_t at = in.pos();
        buffer.resize(n * scalar_size);
        in.read_bytes(buffer.data(), buffer.size(), name);
        for (uint64_t i = 0; i < n; ++i) {
            const unsigned char* p = buffer.data() + i * scalar_size;
            float value;
            if (scalar_size == 2) {
                uint16_t bits;
                std::memcpy(&bits, p, 2);
                value = static_cast<float>(Eigen::numext::bit_cast<Eigen::half>(bits));
            } else if (scalar_size == 4) {
                std::memcpy(&value, p, 4);
            } else {
                double d;
                std::memcpy(&d, p, 8);
                value = static_cast<float>(d);
                if (std::isfinite(d) && !std::isfinite(value))
                    in.fail_at(at + i * scalar_size,
                               "{} holds {} at row {}, column {}, beyond the float32 range", name,
                               d, (done + i) / row_length, (done + i) % row_length);
            }
            if (!std::isfinite(value))
                in.fail_at(at + i * scalar_size, "{} holds {} at row {}, column {}", name,
                           std::isnan(value) ? "NaN" : "Inf", (done + i) / row_length,
                           (done + i) % row_length);
            out[done + i] = value;
        }
        done += n;
        progress.advance(n * scalar_size);
    }
}

Factor load_factor(FileReader& in, const FactorPlan& plan, Progress& progress) {
    Factor f;
    f.scalar_size = plan.scalar_size;
    f.s.resize(static_cast<Eigen::Index>(plan.k));
    f.u.resize(static_cast<Eigen::Index>(plan.rows), static_cast<Eigen::Index>(plan.k));
    f.sxv.resize(static_cast<Eigen::Index>(plan.cols), static_cast<Eigen::Index>(plan.k));
    const uint64_t k = std::max<uint64_t>(plan.k, 1);
    in.seek(plan.s_at);
    read_scalars(in, plan.scalar_size, f.s.data(), plan.k, "S of " + plan.label, k, progress);
    read_scalars(in, plan.scalar_size, f.u.data(), plan.rows * plan.k, "U matrix of " + plan.label,
                 k, progress);
    read_scalars(in, plan.scalar_size, f.sxv.data(), plan.cols * plan.k,
                 "SxV matrix of " + plan.label, k, progress);
    return f;
}

void check_trailing(FileReader& in, const char* body) {
    if (in.remaining() != 0)
        in.fail_here("{} trailing bytes after the {} body (the file should end here)",
                     in.remaining(), body);
}

}  // namespace

bool probe(const fs::path& path) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) return false;
    std::ifstream in(path, std::ios::binary);
    char head[kMaxSignatureLength] = {};
    in.read(head, sizeof head);
    const std::string start(head, static_cast<size_t>(in.gcount()));
    for (const Signature& s : kSignatures)
        if (start.compare(0, std::strlen(s.text), s.text) == 0) return true;
    return false;
}

std::shared_ptr<const Factorization> read(const fs::path& path, Progress& progress) {
    FileReader in(path);
    const Signature& signature = identify(in);
    auto f = std::make_shared<Factorization>();
    f->body = signature.body;
    f->rotation_block = signature.text[std::strlen(signature.text) - 1] == 'R';

    f->meta = read_meta(in);
    const int nc = f->num_channels();
    f->sampling = read_sampling(in, path.stem().string());
    const uint64_t size_at = in.pos();
    const auto width = in.get<uint32_t>("width");
    const auto height = in.get<uint32_t>("height");
    if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide ||
        uint64_t(width) * height > kMaxTexels)
        in.fail_at(size_at, "declares {}×{} texels (each side must be 1..{}, at most {} texels)",
                   width, height, kMaxSide, kMaxTexels);
    check_image_size(width, height, path.string());
    f->width = static_cast<int>(width);
    f->height = static_cast<int>(height);
    if (f->rotation_block) {
        const uint64_t at = in.pos();
        const auto n = in.get<uint32_t>("rotation count");
        if (uint64_t(n) * 36 > in.remaining())
            in.fail_at(at, "declares {} rotation matrices ({} bytes) but the file ends after {}", n,
                       uint64_t(n) * 36, in.remaining());
        f->rotations.resize(n);
        for (auto& r : f->rotations) in.read_bytes(r.data(), 36, "rotation matrix");
    }

    const uint64_t images = uint64_t(f->sampling.num_views()) * f->sampling.num_lights();
    const uint64_t texels = uint64_t(width) * height;
    std::vector<FactorPlan> plans;
    if (f->body == Body::kDfmf) {
        const uint64_t k_at = in.pos();
        const auto max_k = in.get<uint32_t>("DFMF component count");
        const uint64_t model_at = in.pos();
        f->color_model = in.get<int32_t>("colour model");
        if (f->color_model != kColorModelRgb && f->color_model != kColorModelLogYUV)
            in.fail_at(model_at,
                       "unsupported DFMF colour model {} (btfkit decodes 0 = RGB and 11 = log Y, "
                       "U/Y, V/Y)",
                       f->color_model);
        if (nc != 3)
            in.fail_at(model_at, "colour model {} needs 3 channels but the meta block declares {}",
                       f->color_model, nc);
        for (float& m : f->color_mean) m = in.get<float>("colour mean");
        for (float& m : f->color_transform) m = in.get<float>("colour transform");
        for (int c = 0; c < nc; ++c) {
            FactorPlan plan;
            plan.label = fmt::format("channel {}", c);
            const uint64_t header_at = in.pos();
            plan.scalar_size = in.get<uint8_t>("scalar size");
            check_scalar_size(in, header_at, plan.scalar_size, plan.label);
            plan.k = in.get<uint32_t>("component count");
            plan.rows = in.get<uint32_t>("row count");
            plan.cols = in.get<uint32_t>("column count");
            if (plan.k > max_k)
                in.fail_at(header_at,
                           "{} declares K = {} but the DFMF header's maximum (byte {}) "
                           "is {}",
                           plan.label, plan.k, k_at, max_k);
            plans.push_back(plan_matrices(in, header_at, plan, images, "views × lights", texels));
        }
        check_trailing(in, "DFMF");
    } else {
        if (nc != 3)
            in.fail_here("FMF with {} channels: btfkit decodes FMF with 3 (RGB) channels", nc);
        const uint64_t version_at = in.pos();
        f->fmf_header_version = in.get<uint8_t>("FMF header version");
        if (f->fmf_header_version > 2)
            in.fail_at(version_at, "unsupported FMF header version {} (btfkit reads 0..2)",
                       f->fmf_header_version);
        if (f->fmf_header_version >= 1)
            f->dynamic_range_reduction = in.get<uint32_t>("dynamic range reduction method");
        if (f->fmf_header_version >= 2) {
            const uint64_t at = in.pos();
            const auto rows = in.get<uint32_t>("height map size");
            const auto cols = in.get<uint32_t>("height map size");
            if (rows > kMaxSide || cols > kMaxSide || uint64_t(rows) * cols * 2 > in.remaining())
                in.fail_at(at,
                           "height map declares {}×{} half floats but the file ends after {} "
                           "bytes",
                           rows, cols, in.remaining());
            f->height_map_rows = static_cast<int>(rows);
            f->height_map_cols = static_cast<int>(cols);
            f->height_map.resize(uint64_t(rows) * cols);
            const uint64_t k = std::max<uint64_t>(cols, 1);
            read_scalars(in, 2, f->height_map.data(), f->height_map.size(), "height map", k,
                         Progress::none());
        }
        FactorPlan plan;
        plan.label = "the FMF body";
        const uint64_t header_at = in.pos();
        plan.k = in.get<uint32_t>("component count");
        const uint64_t ss_at = in.pos();
        plan.scalar_size = in.get<uint8_t>("scalar size");
        check_scalar_size(in, ss_at, plan.scalar_size, plan.label);
        const uint64_t k2_at = in.pos();
        const auto k2 = in.get<uint32_t>("component count");
        if (k2 != plan.k)
            in.fail_at(k2_at, "the FMF body declares K = {} and then K = {} (byte {})", plan.k, k2,
                       header_at);
        plan.rows = in.get<uint32_t>("row count");
        plan.cols = in.get<uint32_t>("column count");
        plans.push_back(
            plan_matrices(in, header_at, plan, images * nc, "views × lights × channels", texels));
        check_trailing(in, "FMF");
    }

    uint64_t matrix_bytes = 0;
    for (const FactorPlan& p : plans)
        matrix_bytes += (p.k + p.rows * p.k + p.cols * p.k) * p.scalar_size;
    progress.begin("reading UBO2014 factors", matrix_bytes);
    for (const FactorPlan& p : plans) f->factors.push_back(load_factor(in, p, progress));
    progress.finish();
    return f;
}

}  // namespace btf::ubo2014
