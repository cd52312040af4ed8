// SPDX-License-Identifier: MIT
// Writing UBO2014 `!DFMF08FC` files (FORMATS.md items 1–5) and the exact in-memory factorization
// of small sources that feeds the writer.
//
// Byte layout written (all little-endian; docs/formats.md, "Bonn UBO2014" has the table):
//   signature "!DFMF08FC" (+ "R" with a rotation block)
//   meta: u32 size, u32 version, char[80] × 3, f32 ppmm, f32[3] rgb scale,
//         [v ≥ 2] u32 cosine flag, [v ≥ 3] u32 length + XML, [v ≥ 4] u32 nC + (u32 length + name)
//   u32 nV, per view: f32 θ, f32 φ, u32 nL, nL × (f32 θ, f32 φ)
//   u32 width, u32 height, [R] u32 n + n × f32[9]
//   u32 max K, i32 colour model, f32[3] mean, f32[9] transform
//   per channel: u8 scalar size, u32 K, u32 rows, u32 cols, S[K], U[rows × K], SxV[cols × K]

#include <Eigen/SVD>

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>

#include "btf/core/color.h"
#include "btf/io/ubo2014.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::ubo2014 {

namespace fs = std::filesystem;

namespace {

constexpr float kHalfMax = 65504.0f;
const std::vector<std::string> kRgbChannelNames = {"R", "G", "B"};

class ByteWriter {
  public:
    ByteWriter(const fs::path& temp, std::string name) : m_name(std::move(name)) {
        m_out.open(temp, std::ios::binary | std::ios::trunc);
        if (!m_out) fail("{}: cannot open {} for writing", m_name, temp.string());
    }
    template <typename T>
    void put(T value) {
        bytes(&value, sizeof(T));
    }
    void bytes(const void* data, size_t n) {
        m_out.write(static_cast<const char*>(data), static_cast<std::streamsize>(n));
        if (!m_out) fail("{}: write error (disk full?)", m_name);
        m_written += n;
    }
    void fixed_string(const std::string& s) {
        char raw[80] = {};
        std::memcpy(raw, s.data(), s.size());
        bytes(raw, 80);
    }
    void counted_string(const std::string& s) {
        put<uint32_t>(static_cast<uint32_t>(s.size()));
        bytes(s.data(), s.size());
    }
    // Writes `count` floats as scalars of `scalar_size` bytes.
    void scalars(const float* values, int64_t count, int scalar_size) {
        constexpr int64_t kChunk = 1 << 16;
        std::vector<unsigned char> buffer;
        for (int64_t done = 0; done < count; done += kChunk) {
            const int64_t n = std::min(kChunk, count - done);
            buffer.resize(size_t(n) * scalar_size);
            for (int64_t i = 0; i < n; ++i) {
                if (scalar_size == 2) {
                    const auto bits =
                        Eigen::numext::bit_cast<uint16_t>(Eigen::half(values[done + i]));
                    std::memcpy(&buffer[i * 2], &bits, 2);
                } else {
                    std::memcpy(&buffer[i * 4], &values[done + i], 4);
                }
            }
            bytes(buffer.data(), buffer.size());
        }
    }
    void close() {
        m_out.close();
        if (!m_out) fail("{}: write error while closing", m_name);
    }
    uint64_t written() const { return m_written; }

  private:
    std::string m_name;
    std::ofstream m_out;
    uint64_t m_written = 0;
};

void check_values(const std::string& name, const float* values, int64_t count, int64_t row_length,
                  int scalar_size, const std::string& what) {
    for (int64_t i = 0; i < count; ++i) {
        const float v = values[i];
        check(std::isfinite(v), "{}: {} holds {} at row {}, column {}", name, what,
              std::isnan(v) ? "NaN" : "Inf", i / row_length, i % row_length);
        check(scalar_size != 2 || std::abs(v) <= kHalfMax,
              "{}: {} holds {} at row {}, column {}, beyond the half-float range (±65504); write "
              "scalar size 4 (float32)",
              name, what, v, i / row_length, i % row_length);
    }
}

uint32_t meta_size(const Meta& meta, const std::vector<std::string>& names) {
    uint64_t size = 4 + 4 + 3 * 80 + 4 + 12;
    if (meta.version > 1) size += 4;
    if (meta.version > 2) size += 4 + meta.xml.size();
    if (meta.version > 3) {
        size += 4;
        for (const std::string& n : names) size += 4 + n.size();
    }
    return static_cast<uint32_t>(size);
}

}  // namespace

void write_dfmf(const fs::path& path, const Factorization& f, Progress& progress) {
    const std::string name = path.string();
    check(f.body == Body::kDfmf, "{}: btfkit writes DFMF bodies only (this factorization is FMF)",
          name);
    f.validate(name);
    const Meta& meta = f.meta;
    check(meta.version >= 1 && meta.version <= 4, "{}: meta version {} cannot be written (1..4)",
          name, meta.version);
    check(!meta.cosine_flag || meta.version >= 2,
          "{}: the cosine flag needs meta version ≥ 2 (version is {})", name, meta.version);
    check(meta.xml.empty() || meta.version >= 3,
          "{}: an XML string needs meta version ≥ 3 (version is {})", name, meta.version);
    check(meta.channel_names.empty() || meta.version >= 4,
          "{}: channel names need meta version 4 (version is {})", name, meta.version);
    for (const auto* s : {&meta.measurement_setup, &meta.image_sensor, &meta.light_source})
        check(s->size() <= 80, "{}: meta string '{}' is {} bytes; the field holds 80", name, *s,
              s->size());
    check(meta.xml.size() < (uint64_t(1) << 31), "{}: XML string too long", name);
    const std::vector<std::string>& names =
        meta.channel_names.empty() ? kRgbChannelNames : meta.channel_names;
    for (const Factor& factor : f.factors)
        check(factor.scalar_size == 2 || factor.scalar_size == 4,
              "{}: scalar size {} cannot be written (2 = half or 4 = float32)", name,
              factor.scalar_size);
    for (size_t c = 0; c < f.factors.size(); ++c) {
        const Factor& factor = f.factors[c];
        const int64_t k = std::max<int64_t>(factor.components(), 1);
        const std::string channel = fmt::format(" of channel {}", c);
        check_values(name, factor.s.data(), factor.s.size(), k, factor.scalar_size, "S" + channel);
        check_values(name, factor.u.data(), factor.u.size(), k, factor.scalar_size,
                     "U matrix" + channel);
        check_values(name, factor.sxv.data(), factor.sxv.size(), k, factor.scalar_size,
                     "SxV matrix" + channel);
    }
    for (float v : f.color_mean) check(std::isfinite(v), "{}: colour mean is not finite", name);
    for (float v : f.color_transform)
        check(std::isfinite(v), "{}: colour transform is not finite", name);

    AtomicOutput output(path);
    ByteWriter out(output.temp_path(), name);
    const std::string signature = f.signature();
    out.bytes(signature.data(), signature.size());

    const uint32_t size = meta_size(meta, names);
    const uint64_t meta_start = out.written();
    out.put<uint32_t>(size);
    out.put<uint32_t>(meta.version);
    out.fixed_string(meta.measurement_setup);
    out.fixed_string(meta.image_sensor);
    out.fixed_string(meta.light_source);
    out.put<float>(meta.ppmm);
    for (float s : meta.rgb_scale_factor) out.put<float>(s);
    if (meta.version > 1) out.put<uint32_t>(meta.cosine_flag ? 1 : 0);
    if (meta.version > 2) out.counted_string(meta.xml);
    if (meta.version > 3) {
        out.put<uint32_t>(static_cast<uint32_t>(names.size()));
        for (const std::string& n : names) out.counted_string(n);
    }
    check(out.written() - meta_start == size, "{}: internal error: meta block size {} != {}", name,
          out.written() - meta_start, size);

    const Sampling& s = f.sampling;
    out.put<uint32_t>(static_cast<uint32_t>(s.num_views()));
    for (int v = 0; v < s.num_views(); ++v) {
        out.put<float>(static_cast<float>(s.views[v].theta));
        out.put<float>(static_cast<float>(s.views[v].phi));
        out.put<uint32_t>(static_cast<uint32_t>(s.num_lights()));
        for (int l = 0; l < s.num_lights(); ++l) {
            out.put<float>(static_cast<float>(s.lights[l].theta));
            out.put<float>(static_cast<float>(s.lights[l].phi));
        }
    }
    out.put<uint32_t>(static_cast<uint32_t>(f.width));
    out.put<uint32_t>(static_cast<uint32_t>(f.height));
    if (f.rotation_block) {
        out.put<uint32_t>(static_cast<uint32_t>(f.rotations.size()));
        for (const auto& r : f.rotations) out.bytes(r.data(), 36);
    }

    int max_k = 0;
    for (const Factor& factor : f.factors) max_k = std::max(max_k, factor.components());
    out.put<uint32_t>(static_cast<uint32_t>(max_k));
    out.put<int32_t>(f.color_model);
    for (float v : f.color_mean) out.put<float>(v);
    for (float v : f.color_transform) out.put<float>(v);

    progress.begin("writing DFMF", f.factors.size());
    for (const Factor& factor : f.factors) {
        out.put<uint8_t>(static_cast<uint8_t>(factor.scalar_size));
        out.put<uint32_t>(static_cast<uint32_t>(factor.components()));
        out.put<uint32_t>(static_cast<uint32_t>(factor.u.rows()));
        out.put<uint32_t>(static_cast<uint32_t>(factor.sxv.rows()));
        out.scalars(factor.s.data(), factor.s.size(), factor.scalar_size);
        out.scalars(factor.u.data(), factor.u.size(), factor.scalar_size);
        out.scalars(factor.sxv.data(), factor.sxv.size(), factor.scalar_size);
        progress.advance();
    }
    out.close();
    output.commit();
    progress.finish();
}

Factorization factorize(const BtfSource& source, const FactorizeOptions& options,
                        Progress& progress) {
    const std::string name =
        source.info().path.empty() ? source.info().format : source.info().path.string();
    const Sampling& sampling = source.sampling();
    const int64_t images = sampling.num_images();
    const int64_t texels = source.num_texels();
    check(options.color_model == kColorModelRgb || options.color_model == kColorModelLogYUV,
          "{}: cannot factorize into colour model {} (btfkit writes 0 = RGB and 11 = log Y, U/Y, "
          "V/Y)",
          name, options.color_model);
    check(options.scalar_size == 2 || options.scalar_size == 4,
          "{}: scalar size {} cannot be written (2 = half or 4 = float32)", name,
          options.scalar_size);
    check(options.components >= 1, "{}: K = {} components; need at least 1", name,
          options.components);
    check(images > 0 && texels > 0, "{}: empty source", name);
    check(images * texels <= options.max_samples,
          "{}: {} images × {} texels = {} samples per channel exceed the exact in-memory "
          "factorization's limit of {}; use a smaller source (fewer views or texels)",
          name, images, texels, images * texels, options.max_samples);

    Factorization f;
    f.body = Body::kDfmf;
    f.meta = options.meta;
    f.sampling = sampling;
    f.width = source.width();
    f.height = source.height();
    f.color_model = options.color_model;

    // One matrix per channel: row = view·nL + light, column = y·W + x.
    std::array<RowMatrix, 3> a;
    for (RowMatrix& m : a) m.resize(images, texels);
    const int nl = sampling.num_lights();
    progress.begin("reading images for the factorization", static_cast<uint64_t>(images));
    parallel_for(0, images, [&](int64_t row) {
        Image image;
        const int view = static_cast<int>(row / nl), light = static_cast<int>(row % nl);
        source.read_image(view, light, image);
        const float cosine = options.meta.cosine_flag
                                 ? std::max(float(sampling.lights.vector(light).z), kMinLightCosine)
                                 : 1.0f;
        for (int64_t t = 0; t < texels; ++t) {
            const float* p = image.data() + 3 * t;
            const Rgb rgb = Rgb{p[0], p[1], p[2]} * cosine;
            std::array<float, 3> c{rgb.r, rgb.g, rgb.b};
            if (options.color_model == kColorModelLogYUV) c = rgb_to_ubo_model11(rgb);
            for (int ch = 0; ch < 3; ++ch) a[ch](row, t) = c[ch];
        }
        progress.advance();
    });
    progress.begin("factorizing channels (exact SVD)", 3);
    const int k = static_cast<int>(std::min<int64_t>(options.components, std::min(images, texels)));
    for (int ch = 0; ch < 3; ++ch) {
        Eigen::MatrixXd m = a[ch].cast<double>();
        a[ch].resize(0, 0);
        Eigen::BDCSVD<Eigen::MatrixXd> svd(m, Eigen::ComputeThinU | Eigen::ComputeThinV);
        m.resize(0, 0);
        Factor factor;
        factor.scalar_size = options.scalar_size;
        factor.s = svd.singularValues().head(k).cast<float>();
        factor.u = svd.matrixU().leftCols(k).cast<float>();
        factor.sxv =
            (svd.matrixV().leftCols(k) * svd.singularValues().head(k).asDiagonal()).cast<float>();
        f.factors.push_back(std::move(factor));
        progress.advance();
    }
    progress.finish();
    return f;
}

void write_dfmf(const fs::path& path, const BtfSource& source, const FactorizeOptions& options,
                Progress& progress) {
    write_dfmf(path, factorize(source, options, progress), progress);
}

}  // namespace btf::ubo2014
