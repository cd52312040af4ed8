// SPDX-License-Identifier: MIT
#include "fuzz/support/package_mutator.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "btf/io/package.h"

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

namespace btf::fuzz {

namespace {

using json = nlohmann::json;
using Rng = std::mt19937_64;

constexpr uint8_t kMagic[8] = {0x89, 'B', 'T', 'F', 'P', 'K', 'G', '\n'};
// Largest decoded section the mutator unpacks to mutate (larger ones are left alone).
constexpr uint64_t kMaxUnpacked = uint64_t(16) << 20;

uint32_t get_u32(const uint8_t* p) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t{p[i]} << (8 * i);
    return v;
}

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
}

void put_u64(std::vector<uint8_t>& out, uint64_t v) {
    for (int i = 0; i < 8; ++i) out.push_back(uint8_t(v >> (8 * i)));
}

std::string hex64(uint64_t v) {
    static const char digits[] = "0123456789abcdef";
    std::string s(16, '0');
    for (int i = 15; i >= 0; --i, v >>= 4) s[size_t(i)] = digits[v & 15];
    return s;
}

// A package's layout as the bytes say, nothing checked: the header and the stored bytes of the
// sections that the section table places inside the file.
struct Layout {
    uint32_t version = 0;
    json header;
    std::vector<std::vector<uint8_t>> stored;  // of sections 0 .. stored.size() - 1
};

std::optional<Layout> parse(const uint8_t* data, size_t size) {
    if (size < size_t(kPackagePreamble) || std::memcmp(data, kMagic, sizeof kMagic) != 0)
        return std::nullopt;
    const uint32_t header_size = get_u32(data + 12);
    if (header_size > size - kPackagePreamble) return std::nullopt;
    Layout layout;
    layout.version = get_u32(data + 8);
    const uint8_t* text = data + kPackagePreamble;
    layout.header = json::parse(text, text + header_size, nullptr, false);
    if (layout.header.is_discarded() || !layout.header.is_object()) return std::nullopt;
    const auto sections = layout.header.find("sections");
    if (sections == layout.header.end() || !sections->is_array()) return std::nullopt;
    const uint64_t start = kPackagePreamble + uint64_t(header_size);
    const uint64_t available = size - start;
    for (const json& e : *sections) {
        if (!e.is_object()) break;
        const auto offset = e.find("offset"), stored = e.find("size");
        if (offset == e.end() || stored == e.end() || !offset->is_number_unsigned() ||
            !stored->is_number_unsigned())
            break;
        const uint64_t o = offset->get<uint64_t>(), n = stored->get<uint64_t>();
        if (o > available || n > available - o) break;
        layout.stored.emplace_back(data + start + o, data + start + o + n);
    }
    return layout;
}

std::vector<uint8_t> preamble_and_header(uint32_t version, const json& header) {
    const std::string text = header.dump(-1, ' ', false, json::error_handler_t::replace);
    std::vector<uint8_t> out(std::begin(kMagic), std::end(kMagic));
    put_u32(out, version);
    put_u32(out, uint32_t(text.size()));
    put_u64(out, XXH64(text.data(), text.size(), 0));
    out.insert(out.end(), text.begin(), text.end());
    return out;
}

// Writes the layout as a package: sections back to back, the table's offsets, sizes and
// checksums made to match (and raw_size for raw sections).
std::vector<uint8_t> serialize(Layout& layout) {
    json& sections = layout.header["sections"];
    if (!sections.is_array()) sections = json::array();
    uint64_t offset = 0;
    for (size_t i = 0; i < layout.stored.size() && i < sections.size(); ++i) {
        json& e = sections[i];
        if (!e.is_object()) continue;
        const std::vector<uint8_t>& s = layout.stored[i];
        e["offset"] = offset;
        e["size"] = uint64_t(s.size());
        e["xxh64"] = hex64(XXH64(s.data(), s.size(), 0));
        const auto coding = e.find("coding");
        if (coding != e.end() && *coding == "raw") e["raw_size"] = uint64_t(s.size());
        offset += s.size();
    }
    std::vector<uint8_t> out = preamble_and_header(layout.version, layout.header);
    for (const std::vector<uint8_t>& s : layout.stored) out.insert(out.end(), s.begin(), s.end());
    return out;
}

// After a byte-level mutation: the checksums of whatever layout the bytes have now, the data
// part kept as it is (offsets and sizes are not touched).
std::optional<std::vector<uint8_t>> fix_checksums(const uint8_t* data, size_t size) {
    std::optional<Layout> layout = parse(data, size);
    if (!layout) return std::nullopt;
    json& sections = layout->header["sections"];
    for (size_t i = 0; i < layout->stored.size(); ++i) {
        const std::vector<uint8_t>& s = layout->stored[i];
        sections[i]["xxh64"] = hex64(XXH64(s.data(), s.size(), 0));
    }
    const uint64_t start = kPackagePreamble + uint64_t(get_u32(data + 12));
    std::vector<uint8_t> out = preamble_and_header(layout->version, layout->header);
    out.insert(out.end(), data + start, data + size);
    return out;
}

// ---- header mutations --------------------------------------------------------------------------

json edge_number(Rng& rng) {
    static const json kValues[] = {
        0,
        1,
        -1,
        2,
        3,
        4,
        7,
        8,
        16,
        255,
        256,
        65535,
        65536,
        int64_t(1) << 31,
        (int64_t(1) << 31) - 1,
        -(int64_t(1) << 31),
        int64_t(1) << 32,
        int64_t(1) << 40,
        std::numeric_limits<int64_t>::max(),
        std::numeric_limits<int64_t>::min(),
        std::numeric_limits<uint64_t>::max(),
        0.5,
        1.5,
        -0.0,
        1e-30,
        1e30,
        1e308,
        -1e308,
        65504.0,
        3.4e38,
    };
    return kValues[rng() % std::size(kValues)];
}

json mutate_number(const json& v, Rng& rng) {
    switch (rng() % 4) {
        case 0:
            return edge_number(rng);
        // Integer arithmetic wraps around (in unsigned): an overflow here is the point, not a bug.
        case 1:
            if (v.is_number_integer())
                return int64_t(uint64_t(v.get<int64_t>()) + uint64_t(rng() % 5) - 2);
            return v.get<double>() * 1.0001;
        case 2:
            if (v.is_number_integer()) return int64_t(uint64_t(v.get<int64_t>()) << 1);
            return -v.get<double>();
        default:
            if (v.is_number_integer()) return double(v.get<int64_t>()) + 0.5;
            return std::floor(v.get<double>());
    }
}

json mutate_string(const json& v, Rng& rng) {
    static const char* const kStrings[] = {
        "",      "fmf",        "pca-views", "lpca",  "mlvq",        "perceptual", "bsvtf",
        "raw",   "zstd",       "f16",       "f32",   "u8",          "rgb",        "ycbcr",
        "lab",   "ubo81",      "x",         "\xff",  "0",           "-1",         "tables",
        "means", "components", "u0",        "tiles", "tiles.index", "1e999",      "dome151",
    };
    if (rng() % 2 == 0) return kStrings[rng() % std::size(kStrings)];
    std::string s = v.get<std::string>();
    const size_t max = s.size() * 2 + 16;
    s.resize(max);
    const size_t n =
        LLVMFuzzerMutate(reinterpret_cast<uint8_t*>(s.data()), v.get<std::string>().size(), max);
    s.resize(std::min(n, max));
    return s;
}

json other_type(Rng& rng) {
    switch (rng() % 6) {
        case 0:
            return nullptr;
        case 1:
            return true;
        case 2:
            return "x";
        case 3:
            return json::array();
        case 4:
            return json::object();
        default:
            return edge_number(rng);
    }
}

// Every value of the header with its JSON pointer; containers too.
void collect(const json& v, const json::json_pointer& at, std::vector<json::json_pointer>& out) {
    out.push_back(at);
    if (v.is_object()) {
        for (const auto& [key, child] : v.items()) collect(child, at / key, out);
    } else if (v.is_array()) {
        for (size_t i = 0; i < v.size(); ++i) collect(v[i], at / i, out);
    }
}

bool mutate_header(json& header, Rng& rng) {
    std::vector<json::json_pointer> all;
    collect(header, json::json_pointer(), all);
    // Mostly the codec's own fields: the section table is rewritten by serialize() anyway.
    std::vector<json::json_pointer> picks;
    for (const json::json_pointer& p : all)
        if (p.empty() || p.to_string().rfind("/sections", 0) != 0 || rng() % 8 == 0)
            picks.push_back(p);
    if (picks.empty()) return false;
    const json::json_pointer at = picks[rng() % picks.size()];
    json& v = header[at];
    if (v.is_object()) {
        if (!v.empty() && rng() % 2 == 0) {
            auto it = v.begin();
            std::advance(it, long(rng() % v.size()));
            v.erase(it);
        } else {
            v["fuzz"] = other_type(rng);
        }
    } else if (v.is_array()) {
        if (v.empty()) {
            v.push_back(edge_number(rng));
        } else if (rng() % 3 == 0) {
            v.erase(v.begin() + long(rng() % v.size()));
        } else if (rng() % 2 == 0) {
            const json copy = v[rng() % v.size()];
            v.insert(v.begin() + long(rng() % (v.size() + 1)), copy);
        } else {
            std::swap(v[rng() % v.size()], v[rng() % v.size()]);
        }
    } else if (rng() % 8 == 0) {
        v = other_type(rng);
    } else if (v.is_number()) {
        v = mutate_number(v, rng);
    } else if (v.is_string()) {
        v = mutate_string(v, rng);
    } else {
        v = other_type(rng);
    }
    return true;
}

// ---- section mutations -------------------------------------------------------------------------

// A section's decoded bytes (unpacking a zstd frame); nullopt when it cannot be had.
std::optional<std::vector<uint8_t>> decoded(const json& entry, const std::vector<uint8_t>& stored) {
    const auto coding = entry.find("coding");
    if (coding == entry.end() || *coding != "zstd") return stored;
    const unsigned long long n = ZSTD_getFrameContentSize(stored.data(), stored.size());
    if (n == ZSTD_CONTENTSIZE_UNKNOWN || n == ZSTD_CONTENTSIZE_ERROR || n > kMaxUnpacked)
        return std::nullopt;
    std::vector<uint8_t> out(n);
    const size_t got = ZSTD_decompress(out.data(), out.size(), stored.data(), stored.size());
    if (ZSTD_isError(got) || got != n) return std::nullopt;
    return out;
}

void poke_values(std::vector<uint8_t>& data, Rng& rng) {
    static const float kFloats[] = {
        std::numeric_limits<float>::quiet_NaN(),
        std::numeric_limits<float>::infinity(),
        -std::numeric_limits<float>::infinity(),
        std::numeric_limits<float>::max(),
        std::numeric_limits<float>::denorm_min(),
        -0.0f,
        0.0f,
        1.0f,
        -1.0f,
        65504.0f,
        1e30f,
    };
    static const uint16_t kHalves[] = {0x7e00, 0x7c00, 0xfc00, 0x7bff, 0xfbff, 0x0001, 0x8000};
    static const uint32_t kInts[] = {0, 1, 0x7fffffff, 0x80000000, 0xffffffff, 0x10000, 0xffff};
    const int pokes = 1 + int(rng() % 4);
    const int kind = int(rng() % 3);
    const size_t width = kind == 1 ? 2 : 4;
    if (data.size() < width) return;
    for (int i = 0; i < pokes; ++i) {
        const size_t at = (rng() % (data.size() / width)) * width;
        if (kind == 0) {
            const float f = kFloats[rng() % std::size(kFloats)];
            std::memcpy(&data[at], &f, 4);
        } else if (kind == 1) {
            const uint16_t h = kHalves[rng() % std::size(kHalves)];
            std::memcpy(&data[at], &h, 2);
        } else {
            const uint32_t v = kInts[rng() % std::size(kInts)];
            std::memcpy(&data[at], &v, 4);
        }
    }
}

bool mutate_section(Layout& layout, size_t budget, Rng& rng) {
    if (layout.stored.empty()) return false;
    const size_t i = rng() % layout.stored.size();
    json& entry = layout.header["sections"][i];
    std::optional<std::vector<uint8_t>> data = decoded(entry, layout.stored[i]);
    if (!data) return false;
    if (rng() % 3 == 0) {
        poke_values(*data, rng);
    } else {
        const size_t max = std::min(budget, data->size() * 2 + 64);
        if (max < data->size()) return false;
        const size_t old = data->size();
        data->resize(max);
        data->resize(LLVMFuzzerMutate(data->data(), old, max));
    }
    entry["coding"] = "raw";
    layout.stored[i] = std::move(*data);
    return true;
}

bool mutate_section_list(Layout& layout, Rng& rng) {
    json& sections = layout.header["sections"];
    if (sections.empty()) return false;
    if (rng() % 2 == 0 && !layout.stored.empty()) {
        // A prefix, as a partly streamed package is: the table keeps declaring every section.
        layout.stored.resize(rng() % layout.stored.size());
    } else {
        const size_t i = rng() % sections.size();
        sections.erase(sections.begin() + long(i));
        if (i < layout.stored.size()) layout.stored.erase(layout.stored.begin() + long(i));
    }
    return true;
}

size_t mutate_bytes(uint8_t* data, size_t size, size_t max_size) {
    const size_t n = LLVMFuzzerMutate(data, size, max_size);
    std::optional<std::vector<uint8_t>> fixed = fix_checksums(data, n);
    if (!fixed || fixed->size() > max_size) return n;
    std::memcpy(data, fixed->data(), fixed->size());
    return fixed->size();
}

}  // namespace

size_t mutate_package(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
    Rng rng(seed);
    std::optional<Layout> layout = parse(data, size);
    const int choice = int(rng() % 8);
    if (!layout || choice == 0) return mutate_bytes(data, size, max_size);
    try {
        bool changed = false;
        if (choice <= 3)
            changed = mutate_header(layout->header, rng);
        else if (choice <= 6)
            changed = mutate_section(*layout, max_size, rng);
        else
            changed = mutate_section_list(*layout, rng);
        if (changed) {
            const std::vector<uint8_t> out = serialize(*layout);
            if (out.size() <= max_size) {
                std::memcpy(data, out.data(), out.size());
                return out.size();
            }
        }
    } catch (const json::exception&) {
        // A mutation the JSON library refused (e.g. a pointer into a changed container).
    }
    return mutate_bytes(data, size, max_size);
}

}  // namespace btf::fuzz
