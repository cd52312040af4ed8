// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/codebooks.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "btf/core/color.h"
#include "btf/util/error.h"
#include "btf/util/limits.h"

namespace btf::mlvq {

std::string to_string(ColourModel model) {
    return model == ColourModel::kYCbCr ? "ycbcr" : "logluv";
}

ColourModel parse_colour_model(const std::string& text) {
    if (text == "ycbcr") return ColourModel::kYCbCr;
    if (text == "logluv") return ColourModel::kLogLuv;
    fail("colour model '{}': expected ycbcr or logluv", text);
}

std::array<float, 3> to_planes(ColourModel model, const Rgb& rgb) {
    if (model == ColourModel::kYCbCr) {
        const YCbCr c = rgb_to_ycbcr(rgb);
        return {std::max(c.y, 0.0f), c.cb, c.cr};
    }
    // LogLuv's chromaticity; its luminance stays linear here (the code-books are PDFs).
    const Xyz xyz = rgb_to_xyz(rgb);
    const LogLuv luv = xyz_to_logluv(xyz);
    return {float(std::max(xyz.y, 0.0)), float(luv.u), float(luv.v)};
}

Rgb from_planes(ColourModel model, float y, float c1, float c2) {
    if (model == ColourModel::kYCbCr) return ycbcr_to_rgb({y, c1, c2});
    if (!(y > 0)) return {0, 0, 0};
    return xyz_to_rgb(luminance_uv_to_xyz(y, c1, c2));
}

namespace {

template <typename Entries>
void check_indices(const Entries& entries, size_t limit, const std::string& what, const char* book,
                   const char* target) {
    for (size_t i = 0; i < entries.size(); ++i) {
        uint32_t index;
        if constexpr (std::is_same_v<typename Entries::value_type, IndexScale>)
            index = entries[i].index;
        else
            index = entries[i];
        if (index >= limit)
            fail("{}: {} entry {} points to {} {} of {}", what, book, i, target, index, limit);
    }
}

void check_scales(const std::vector<IndexScale>& entries, const std::string& what,
                  const char* book) {
    for (size_t i = 0; i < entries.size(); ++i)
        if (!std::isfinite(entries[i].scale) || entries[i].scale < 0)
            fail("{}: {} entry {} has scale {}", what, book, i, entries[i].scale);
}

}  // namespace

void Codebooks::validate(const std::string& what) const {
    grid.validate();
    if (p1.size() % size_t(grid.n_beta) || p2.size() % size_t(grid.n_alpha) ||
        p3.size() % size_t(grid.n_theta_v) || p4.size() % size_t(grid.n_phi_v) ||
        i1.size() % size_t(grid.n_beta) || i2.size() % size_t(grid.n_alpha))
        fail("{}: code-book sizes do not match the grid", what);
    for (size_t i = 0; i < p1.size(); ++i)
        if (!std::isfinite(p1[i])) fail("{}: P1 value {} is not finite", what, i);
    for (size_t i = 0; i < c.size(); ++i)
        if (!std::isfinite(c[i][0]) || !std::isfinite(c[i][1]))
            fail("{}: C entry {} is not finite", what, i);
    check_indices(p2, size_p1(), what, "P2", "P1");
    check_scales(p2, what, "P2");
    for (size_t i = 0; i < m.size(); ++i) {
        if (m[i][0] >= size_p2())
            fail("{}: M entry {} points to P2 {} of {}", what, i, m[i][0], size_p2());
        if (m[i][1] >= size_i2())
            fail("{}: M entry {} points to I2 {} of {}", what, i, m[i][1], size_i2());
    }
    check_indices(p3, size_m(), what, "P3", "M");
    check_scales(p3, what, "P3");
    check_indices(p4, size_p3(), what, "P4", "P3");
    check_scales(p4, what, "P4");
    check_indices(i1, size_c(), what, "I1", "C");
    check_indices(i2, size_i1(), what, "I2", "I1");
}

std::array<float, 3> Codebooks::sample(const IndexScale& p6, int m_, int k, int i, int j) const {
    const IndexScale& e4 = p4[size_t(p6.index) * grid.n_phi_v + m_];
    const IndexScale& e3 = p3[size_t(e4.index) * grid.n_theta_v + k];
    const std::array<uint32_t, 2>& merge = m[e3.index];
    const IndexScale& e2 = p2[size_t(merge[0]) * grid.n_alpha + i];
    const float y =
        p6.scale * e4.scale * e3.scale * e2.scale * p1[size_t(e2.index) * grid.n_beta + j];
    const uint32_t first = i2[size_t(merge[1]) * grid.n_alpha + i];
    const std::array<float, 2>& chroma = c[i1[size_t(first) * grid.n_beta + j]];
    return {y, chroma[0], chroma[1]};
}

int index_bits(size_t n) {
    int bits = 0;
    while (bits < 32 && (size_t(1) << bits) < n) ++bits;
    return bits;
}

StorageSizes storage_sizes(const Codebooks& b, int64_t texels, bool hdr) {
    // Per code-book: its entries, and counts of indices (with the size of the code-book they
    // point into) and of float values (with their compact bits).
    struct Part {
        int64_t count;
        size_t target;  // 0: a float
        int float_bits;
    };
    struct Book {
        const char* name;
        int64_t entries;
        std::vector<Part> parts;
    };
    const std::vector<Book> books = {
        {"P1", int64_t(b.size_p1()), {{int64_t(b.p1.size()), 0, 8}}},
        {"P2",
         int64_t(b.size_p2()),
         {{int64_t(b.p2.size()), b.size_p1(), 0}, {int64_t(b.p2.size()), 0, hdr ? 16 : 8}}},
        {"M",
         int64_t(b.size_m()),
         {{int64_t(b.m.size()), b.size_p2(), 0}, {int64_t(b.m.size()), b.size_i2(), 0}}},
        {"P3",
         int64_t(b.size_p3()),
         {{int64_t(b.p3.size()), b.size_m(), 0}, {int64_t(b.p3.size()), 0, 8}}},
        {"P4",
         int64_t(b.size_p4()),
         {{int64_t(b.p4.size()), b.size_p3(), 0}, {int64_t(b.p4.size()), 0, 8}}},
        {"C", int64_t(b.size_c()), {{int64_t(b.c.size()) * 2, 0, 8}}},
        {"I1", int64_t(b.size_i1()), {{int64_t(b.i1.size()), b.size_c(), 0}}},
        {"I2", int64_t(b.size_i2()), {{int64_t(b.i2.size()), b.size_i1(), 0}}},
        {"P6", texels, {{texels, b.size_p4(), 0}, {texels, 0, 8}}},
    };
    StorageSizes s;
    std::array<int64_t, 4> bits{};
    for (const Book& book : books) {
        int64_t compact_bits = 0;
        for (const Part& p : book.parts) {
            const bool is_float = p.target == 0;
            const int compact = is_float ? p.float_bits : index_bits(p.target);
            bits[0] += p.count * 32;
            bits[1] += p.count * (is_float ? 32 : compact);
            bits[2] += p.count * (is_float ? compact : 32);
            bits[3] += p.count * compact;
            compact_bits += p.count * compact;
        }
        s.books.emplace_back(book.name, book.entries, (compact_bits + 7) / 8);
    }
    for (int i = 0; i < 4; ++i) s.bytes[size_t(i)] = (bits[size_t(i)] + 7) / 8;
    return s;
}

// ---- storage -----------------------------------------------------------------------------------

namespace {

class BitWriter {
  public:
    explicit BitWriter(std::vector<uint8_t>& out) : m_out(out) {}
    void put(uint32_t value, int bits) {
        for (int b = 0; b < bits; ++b) {
            if (m_bit == 0) m_out.push_back(0);
            if ((value >> b) & 1u) m_out.back() |= uint8_t(1u << m_bit);
            m_bit = (m_bit + 1) & 7;
        }
    }
    void align() { m_bit = 0; }

  private:
    std::vector<uint8_t>& m_out;
    int m_bit = 0;
};

class BitReader {
  public:
    BitReader(const std::vector<uint8_t>& in, std::string what)
        : m_in(in), m_what(std::move(what)) {}
    uint32_t get(int bits) {
        if (int64_t(m_pos) * 8 + m_bit + bits > int64_t(m_in.size()) * 8)
            fail("section '{}' is too short", m_what);
        uint32_t value = 0;
        for (int b = 0; b < bits; ++b) {
            if ((m_in[m_pos] >> m_bit) & 1u) value |= 1u << b;
            if (++m_bit == 8) {
                m_bit = 0;
                ++m_pos;
            }
        }
        return value;
    }
    void align() {
        if (m_bit) {
            m_bit = 0;
            ++m_pos;
        }
    }
    /// Before allocating `count` entries of `bits_each` bits: the section must hold them. Entries
    /// of no bits (indices into a one-entry code-book) are bounded by the allocation limit.
    void reserve(uint64_t count, int bits_each, size_t entry_bytes, std::string_view book) {
        const uint64_t left = (uint64_t(m_in.size()) - m_pos) * 8 - uint64_t(m_bit);
        const auto bits = checked_bytes(count, uint64_t(bits_each));
        if (!bits || *bits > left)
            fail("section '{}' is too short for the {} entries of {} its header declares", m_what,
                 count, book);
        check_alloc(checked_bytes(count, entry_bytes).value_or(UINT64_MAX), m_what,
                    fmt::format("code-book {}", book));
    }
    void finish() {
        align();
        if (m_pos != m_in.size())
            fail("section '{}' holds {} bytes, expected {}", m_what, m_in.size(), m_pos);
    }

  private:
    const std::vector<uint8_t>& m_in;
    std::string m_what;
    size_t m_pos = 0;
    int m_bit = 0;
};

// Scales are ratios spanning decades (a dark slice next to a bright one): quantized on a log
// scale between the smallest positive and the largest value; code 0 is an exact 0.
struct Logarithmic {
    double lo = 0, hi = 0;  // natural logs
    int bits = 8;
    static Logarithmic fit(const std::vector<IndexScale>& v, int bits) {
        Logarithmic q;
        q.bits = bits;
        double lo = INFINITY, hi = -INFINITY;
        for (const IndexScale& e : v)
            if (e.scale > 0) {
                lo = std::min(lo, std::log(double(e.scale)));
                hi = std::max(hi, std::log(double(e.scale)));
            }
        if (lo <= hi) {
            q.lo = lo;
            q.hi = hi;
        }
        return q;
    }
    uint32_t max_code() const { return (1u << bits) - 1; }
    uint32_t encode(float x) const {
        if (!(x > 0)) return 0;
        if (!(hi > lo)) return 1;
        const double t = (std::log(double(x)) - lo) / (hi - lo) * (max_code() - 1);
        return 1 + uint32_t(std::clamp(std::lround(t), 0l, long(max_code() - 1)));
    }
    float decode(uint32_t code) const {
        if (code == 0) return 0;
        if (!(hi > lo)) return float(std::exp(lo));
        return float(std::exp(lo + (hi - lo) * (code - 1) / (max_code() - 1)));
    }
    nlohmann::json json() const { return {{"log_lo", lo}, {"log_hi", hi}, {"bits", bits}}; }
    static Logarithmic from(const nlohmann::json& j) {
        const QuantizerFields f = quantizer_fields(j, "log_lo", "log_hi");
        return {f.lo, f.hi, f.bits};
    }
};

void put_entries(BitWriter& w, const std::vector<IndexScale>& v, size_t target,
                 const Logarithmic& q) {
    const int bits = index_bits(target);
    for (const IndexScale& e : v) {
        w.put(e.index, bits);
        w.put(q.encode(e.scale), q.bits);
    }
    w.align();
}

std::vector<IndexScale> get_entries(BitReader& r, size_t count, size_t target, const Logarithmic& q,
                                    std::string_view book) {
    const int bits = index_bits(target);
    r.reserve(count, bits + q.bits, sizeof(IndexScale), book);
    std::vector<IndexScale> v(count);
    for (IndexScale& e : v) {
        e.index = r.get(bits);
        e.scale = q.decode(r.get(q.bits));
    }
    r.align();
    return v;
}

void put_indices(BitWriter& w, const std::vector<uint32_t>& v, size_t target) {
    const int bits = index_bits(target);
    for (uint32_t x : v) w.put(x, bits);
    w.align();
}

std::vector<uint32_t> get_indices(BitReader& r, size_t count, size_t target,
                                  std::string_view book) {
    const int bits = index_bits(target);
    r.reserve(count, bits, sizeof(uint32_t), book);
    std::vector<uint32_t> v(count);
    for (uint32_t& x : v) x = r.get(bits);
    r.align();
    return v;
}

PackageSection section(std::string name, std::vector<uint8_t> data) {
    PackageSection s;
    s.name = std::move(name);
    s.data = std::move(data);
    return s;
}

}  // namespace

void write_codebooks(const Codebooks& b, bool hdr, nlohmann::json& header,
                     std::vector<PackageSection>& sections) {
    b.validate("mlvq code-books");
    const LinearQuantizer qp1 = LinearQuantizer::fit(b.p1.data(), b.p1.size(), 8);
    std::vector<float> c0, c1;
    for (const auto& e : b.c) {
        c0.push_back(e[0]);
        c1.push_back(e[1]);
    }
    const LinearQuantizer qc0 = LinearQuantizer::fit(c0.data(), c0.size(), 8);
    const LinearQuantizer qc1 = LinearQuantizer::fit(c1.data(), c1.size(), 8);
    const Logarithmic q2 = Logarithmic::fit(b.p2, hdr ? 16 : 8);
    const Logarithmic q3 = Logarithmic::fit(b.p3, 8);
    const Logarithmic q4 = Logarithmic::fit(b.p4, 8);

    std::vector<uint8_t> data;
    BitWriter w(data);
    for (float x : b.p1) w.put(qp1.encode(x), qp1.bits);
    w.align();
    put_entries(w, b.p2, b.size_p1(), q2);
    for (const auto& e : b.m) {
        w.put(e[0], index_bits(b.size_p2()));
        w.put(e[1], index_bits(b.size_i2()));
    }
    w.align();
    put_entries(w, b.p3, b.size_m(), q3);
    put_entries(w, b.p4, b.size_p3(), q4);
    for (const auto& e : b.c) {
        w.put(qc0.encode(e[0]), 8);
        w.put(qc1.encode(e[1]), 8);
    }
    w.align();
    put_indices(w, b.i1, b.size_c());
    put_indices(w, b.i2, b.size_i1());
    sections.push_back(section("codebooks", std::move(data)));

    header["grid"] = {{"n_alpha", b.grid.n_alpha},
                      {"n_beta", b.grid.n_beta},
                      {"n_theta_v", b.grid.n_theta_v},
                      {"n_phi_v", b.grid.n_phi_v}};
    header["colour"] = to_string(b.colour);
    header["codebooks"] = {{"P1", b.size_p1()}, {"P2", b.size_p2()}, {"M", b.size_m()},
                           {"P3", b.size_p3()}, {"P4", b.size_p4()}, {"C", b.size_c()},
                           {"I1", b.size_i1()}, {"I2", b.size_i2()}};
    header["quantization"] = {{"P1", qp1.json()}, {"C0", qc0.json()}, {"C1", qc1.json()},
                              {"P2", q2.json()},  {"P3", q3.json()},  {"P4", q4.json()}};
}

Codebooks read_codebooks(const Package& package) {
    const nlohmann::json& h = package.header;
    Codebooks b;
    const nlohmann::json& grid = h.at("grid");
    json_fields::only_keys(grid, "grid", {"n_alpha", "n_beta", "n_theta_v", "n_phi_v"});
    b.grid.n_alpha = int(json_fields::integer_at(grid, "n_alpha", 2, MlvqGrid::kMaxAxis));
    b.grid.n_beta = int(json_fields::integer_at(grid, "n_beta", 2, MlvqGrid::kMaxAxis));
    b.grid.n_theta_v = int(json_fields::integer_at(grid, "n_theta_v", 2, MlvqGrid::kMaxAxis));
    b.grid.n_phi_v = int(json_fields::integer_at(grid, "n_phi_v", 1, MlvqGrid::kMaxAxis));
    b.grid.validate();
    b.colour = parse_colour_model(h.at("colour").get<std::string>());
    const nlohmann::json& sizes = h.at("codebooks");
    json_fields::only_keys(sizes, "codebooks", {"P1", "P2", "M", "P3", "P4", "C", "I1", "I2"});
    auto size = [&](const char* name) {
        return size_t(json_fields::integer_at(sizes, name, 0, int64_t(1) << 31));
    };
    const size_t s1 = size("P1"), s2 = size("P2"), sm = size("M"), s3 = size("P3"), s4 = size("P4"),
                 sc = size("C"), si1 = size("I1"), si2 = size("I2");
    const nlohmann::json& q = h.at("quantization");
    const LinearQuantizer qp1 = LinearQuantizer::from(q.at("P1")),
                          qc0 = LinearQuantizer::from(q.at("C0")),
                          qc1 = LinearQuantizer::from(q.at("C1"));
    const Logarithmic q2 = Logarithmic::from(q.at("P2")), q3 = Logarithmic::from(q.at("P3")),
                      q4 = Logarithmic::from(q.at("P4"));
    const PackageSection* s = package.find("codebooks");
    if (!s) fail("section 'codebooks' is missing");
    BitReader r(s->data, "codebooks");
    const MlvqGrid& g = b.grid;
    r.reserve(s1 * g.n_beta, qp1.bits, sizeof(float), "P1");
    b.p1.resize(s1 * g.n_beta);
    for (float& x : b.p1) x = qp1.decode(r.get(qp1.bits));
    r.align();
    b.p2 = get_entries(r, s2 * g.n_alpha, s1, q2, "P2");
    r.reserve(sm, index_bits(s2) + index_bits(si2), sizeof(b.m[0]), "M");
    b.m.resize(sm);
    for (auto& e : b.m) {
        e[0] = r.get(index_bits(s2));
        e[1] = r.get(index_bits(si2));
    }
    r.align();
    b.p3 = get_entries(r, s3 * g.n_theta_v, sm, q3, "P3");
    b.p4 = get_entries(r, s4 * g.n_phi_v, s3, q4, "P4");
    r.reserve(sc, 16, sizeof(b.c[0]), "C");
    b.c.resize(sc);
    for (auto& e : b.c) {
        e[0] = qc0.decode(r.get(8));
        e[1] = qc1.decode(r.get(8));
    }
    r.align();
    b.i1 = get_indices(r, si1 * g.n_beta, sc, "I1");
    b.i2 = get_indices(r, si2 * g.n_alpha, si1, "I2");
    r.finish();
    b.validate("code-books");
    return b;
}

// ---- the planar index P6 ------------------------------------------------------------------------

int texel_index_levels(int width, int height) {
    int levels = 1;
    while (levels < 4 && (std::min(width, height) >> levels) >= 4) ++levels;
    return levels;
}

namespace {

// The level of texel (x, y): the largest ℓ < levels with x, y multiples of 2^ℓ.
int texel_level(int x, int y, int levels) {
    int level = 0;
    while (level + 1 < levels && x % (2 << level) == 0 && y % (2 << level) == 0) ++level;
    return level;
}

}  // namespace

void write_texel_index(const TexelIndex& index, size_t size_p4, const std::string& prefix,
                       nlohmann::json& header, std::vector<PackageSection>& sections) {
    const int levels = texel_index_levels(index.width, index.height);
    const Logarithmic q = Logarithmic::fit(index.p6, 8);
    const int bits = index_bits(size_p4);
    for (int level = levels - 1; level >= 0; --level) {
        std::vector<uint8_t> data;
        BitWriter w(data);
        for (int y = 0; y < index.height; ++y)
            for (int x = 0; x < index.width; ++x) {
                if (texel_level(x, y, levels) != level) continue;
                const IndexScale& e = index.p6[size_t(y) * index.width + x];
                if (e.index >= size_p4)
                    fail("P6 of texel ({}, {}) points to P4 {} of {}", x, y, e.index, size_p4);
                w.put(e.index, bits);
                w.put(q.encode(e.scale), q.bits);
            }
        sections.push_back(section(fmt::format("{}P6.{}", prefix, level), std::move(data)));
    }
    header["P6"] = q.json();
    header["P6_levels"] = levels;
}

std::vector<IndexScale> read_texel_index(const Package& package, const nlohmann::json& header,
                                         const std::string& prefix, int width, int height,
                                         size_t size_p4) {
    const int levels = texel_index_levels(width, height);
    if (json_fields::integer_at(header, "P6_levels", 1, 16) != levels)
        fail("{} P6 levels for {}×{} texels, expected {}", header.at("P6_levels").dump(), width,
             height, levels);
    const Logarithmic q = Logarithmic::from(header.at("P6"));
    const int bits = index_bits(size_p4);
    // The coarsest level (every 2^(levels−1)-th texel in both directions) must be present and hold
    // its entries before the whole index is allocated: a tiny file cannot claim a huge extent.
    if (const PackageSection* coarsest = package.find(fmt::format("{}P6.{}", prefix, levels - 1))) {
        const uint64_t step = uint64_t(1) << (levels - 1);
        const uint64_t entries =
            ((uint64_t(width) + step - 1) / step) * ((uint64_t(height) + step - 1) / step);
        BitReader(coarsest->data, coarsest->name)
            .reserve(entries, bits + q.bits, sizeof(IndexScale),
                     fmt::format("P6 level {}", levels - 1));
    }
    check_alloc(uint64_t(width) * uint64_t(height) * sizeof(IndexScale), prefix + "P6",
                "the texel index");
    std::vector<IndexScale> p6(size_t(width) * height);
    int finest = levels;  // the finest level present
    for (int level = levels - 1; level >= 0; --level) {
        const PackageSection* s = package.find(fmt::format("{}P6.{}", prefix, level));
        if (!s) break;
        BitReader r(s->data, s->name);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                if (texel_level(x, y, levels) != level) continue;
                IndexScale& e = p6[size_t(y) * width + x];
                e.index = r.get(bits);
                e.scale = q.decode(r.get(q.bits));
                if (e.index >= size_p4)
                    fail("P6 of texel ({}, {}) points to P4 {} of {}", x, y, e.index, size_p4);
            }
        r.finish();
        finest = level;
    }
    if (finest == levels) fail("section '{}P6.{}' is missing", prefix, levels - 1);
    // Texels of levels not received copy the texel of the finest received level below-left.
    if (finest > 0) {
        const int mask = ~((1 << finest) - 1);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x)
                if (texel_level(x, y, levels) < finest)
                    p6[size_t(y) * width + x] = p6[size_t(y & mask) * width + (x & mask)];
    }
    return p6;
}

}  // namespace btf::mlvq
