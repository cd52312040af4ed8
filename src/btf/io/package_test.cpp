// SPDX-License-Identifier: MIT
#include "btf/io/package.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <xxhash.h>
#include <zstd.h>

#include <cstring>
#include <fstream>
#include <random>

#include "btf/testing/support.h"
#include "btf/util/error.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using test::error_of;
using test::TempFolder;
using ::testing::HasSubstr;

using Bytes = std::vector<uint8_t>;

Bytes random_bytes(size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    Bytes b(n);
    for (uint8_t& x : b) x = static_cast<uint8_t>(rng());
    return b;
}

/// Compressible, not trivially: a repeated short pattern with some noise.
Bytes patterned_bytes(size_t n) {
    Bytes b(n);
    for (size_t i = 0; i < n; ++i) b[i] = static_cast<uint8_t>((i % 37) * 7 + (i / 1000));
    return b;
}

PackageSection section(std::string name, Bytes data) {
    PackageSection s;
    s.name = std::move(name);
    s.data = std::move(data);
    return s;
}

/// A package with sections that zstd shrinks, one it cannot shrink and an empty one.
Package sample_package() {
    Package p;
    p.header = {{"codec", "test"}, {"params", {{"rank", 4}, {"scale", 0.5}}}};
    p.sections.push_back(section("means", patterned_bytes(5000)));
    p.sections.push_back(section("noise", random_bytes(300, 7)));
    p.sections.push_back(section("empty", {}));
    p.sections.push_back(section("zeros", Bytes(20000, 0)));
    return p;
}

uint32_t u32_at(const Bytes& b, size_t at) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t{b[at + i]} << (8 * i);
    return v;
}

/// Offset of the first section byte in an encoded package.
size_t data_start(const Bytes& b) {
    return kPackagePreamble + u32_at(b, 12);
}

json header_of(const Bytes& b) {
    return json::parse(b.begin() + kPackagePreamble, b.begin() + long(data_start(b)));
}

/// A package made by hand: preamble with a correct header checksum, `header` dumped as is, then
/// `payload`.
Bytes build(const std::string& header, const Bytes& payload, uint32_t version = kPackageVersion) {
    Bytes b = {0x89, 'B', 'T', 'F', 'P', 'K', 'G', '\n'};
    const auto put = [&](uint64_t v, int n) {
        for (int i = 0; i < n; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
    };
    put(version, 4);
    put(header.size(), 4);
    put(XXH64(header.data(), header.size(), 0), 8);
    b.insert(b.end(), header.begin(), header.end());
    b.insert(b.end(), payload.begin(), payload.end());
    return b;
}

/// `bytes` with its JSON header changed by `edit` (and the header checksum recomputed).
template <typename Edit>
Bytes rebuild(const Bytes& bytes, Edit&& edit) {
    json header = header_of(bytes);
    edit(header);
    return build(header.dump(), Bytes(bytes.begin() + long(data_start(bytes)), bytes.end()));
}

std::string decode_error(const Bytes& bytes) {
    return error_of([&] { decode_package(bytes, "mat.btfpkg"); });
}

Bytes file_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(Package, RoundTripWithRawAndZstdSections) {
    Package p = sample_package();
    const Package original = sample_package();
    const Bytes bytes = encode_package(p, {.zstd_level = 9});
    EXPECT_EQ(p.file_bytes, bytes.size());
    EXPECT_EQ(p.declared_sections, 4);
    EXPECT_EQ(p.header["format"], "btfpkg");
    EXPECT_EQ(p.header["version"], 1);
    EXPECT_EQ(p.header["codec"], "test");

    EXPECT_EQ(p.sections[0].coding, SectionCoding::kZstd);
    EXPECT_LT(p.sections[0].stored_size, 5000u);
    EXPECT_EQ(p.sections[1].coding, SectionCoding::kRaw);  // random bytes do not shrink
    EXPECT_EQ(p.sections[1].stored_size, 300u);
    EXPECT_EQ(p.sections[2].coding, SectionCoding::kRaw);
    EXPECT_EQ(p.sections[2].stored_size, 0u);
    EXPECT_EQ(p.sections[3].coding, SectionCoding::kZstd);
    uint64_t offset = 0;
    for (size_t i = 0; i < p.sections.size(); ++i) {
        const PackageSection& s = p.sections[i];
        EXPECT_EQ(s.data, original.sections[i].data) << s.name;
        EXPECT_EQ(s.offset, offset) << s.name;
        const uint8_t* stored = bytes.data() + data_start(bytes) + s.offset;
        EXPECT_EQ(s.checksum, XXH64(stored, s.stored_size, 0)) << s.name;
        offset += s.stored_size;
    }
    EXPECT_EQ(data_start(bytes) + offset, bytes.size());

    const Package q = decode_package(bytes, "mat.btfpkg");
    EXPECT_TRUE(q.complete());
    EXPECT_EQ(q.declared_sections, 4);
    EXPECT_EQ(q.file_bytes, bytes.size());
    EXPECT_EQ(q.header, p.header);
    ASSERT_EQ(q.sections.size(), p.sections.size());
    for (size_t i = 0; i < q.sections.size(); ++i) {
        const PackageSection &a = p.sections[i], &b = q.sections[i];
        EXPECT_EQ(b.name, a.name);
        EXPECT_EQ(b.data, a.data) << a.name;
        EXPECT_EQ(b.coding, a.coding) << a.name;
        EXPECT_EQ(b.offset, a.offset) << a.name;
        EXPECT_EQ(b.stored_size, a.stored_size) << a.name;
        EXPECT_EQ(b.checksum, a.checksum) << a.name;
    }

    // Deterministic, and re-encoding a decoded package gives the same bytes.
    Package again = sample_package();
    EXPECT_EQ(encode_package(again, {.zstd_level = 9}), bytes);
    Package decoded = q;
    EXPECT_EQ(encode_package(decoded, {.zstd_level = 9}), bytes);
}

TEST(Package, LevelZeroStoresRaw) {
    Package p = sample_package();
    const Bytes bytes = encode_package(p, {.zstd_level = 0});
    for (const PackageSection& s : p.sections) {
        EXPECT_EQ(s.coding, SectionCoding::kRaw) << s.name;
        EXPECT_EQ(s.stored_size, s.data.size()) << s.name;
    }
    const Package q = decode_package(bytes, "raw.btfpkg");
    ASSERT_EQ(q.sections.size(), 4u);
    EXPECT_EQ(q.sections[3].data, Bytes(20000, 0));
    EXPECT_EQ(header_of(bytes)["sections"][0]["coding"], "raw");
}

TEST(Package, GoldenBytes) {
    Package p;
    p.header = {{"codec", "test"}};
    p.sections.push_back(section("data", {1, 2, 3, 4}));
    const std::string text =
        R"({"codec":"test","format":"btfpkg","sections":[{"coding":"raw","name":"data",)"
        R"("offset":0,"raw_size":4,"size":4,"xxh64":"542620e3a2a92ed1"}],"version":1,)"
        R"("writer":"btfkit 0.2.0"})";
    ASSERT_EQ(text.size(), 174u);
    Bytes expected = {
        0x89, 'B',  'T',  'F',  'P',  'K',  'G',  '\n',  // magic
        0x01, 0x00, 0x00, 0x00,                          // version 1
        0xae, 0x00, 0x00, 0x00,                          // header length 174
        0x31, 0x2e, 0x08, 0xe4, 0xfb, 0x68, 0x73, 0xc3,  // XXH64 of the header: c37368fbe4082e31
    };
    expected.insert(expected.end(), text.begin(), text.end());
    expected.insert(expected.end(), {1, 2, 3, 4});

    // The writer as btfkit 0.2.0 names itself (the default is this build's version).
    EXPECT_EQ(encode_package(p, {.zstd_level = 0, .writer = "btfkit 0.2.0"}), expected);
    const Package q = decode_package(expected, "golden.btfpkg");
    EXPECT_EQ(q.codec(), "test");
    ASSERT_EQ(q.sections.size(), 1u);
    EXPECT_EQ(q.at("data").data, Bytes({1, 2, 3, 4}));
    EXPECT_EQ(q.at("data").checksum, 0x542620e3a2a92ed1u);
    EXPECT_EQ(q.file_bytes, 202u);
}

/// Every prefix of a package: on a section boundary it decodes to the sections before that
/// boundary; anywhere else it names the truncated part.
void check_prefixes(const Bytes& bytes) {
    const Package full = decode_package(bytes, "mat.btfpkg");
    const size_t start = data_start(bytes);
    for (size_t length = 0; length <= bytes.size(); ++length) {
        SCOPED_TRACE(fmt::format("prefix of {} of {} bytes", length, bytes.size()));
        const Bytes prefix(bytes.begin(), bytes.begin() + long(length));
        if (length < start) {
            EXPECT_THAT(decode_error(prefix), HasSubstr("mat.btfpkg: truncated in the header"));
            continue;
        }
        const uint64_t available = length - start;
        // Sections wholly present, and the one cut inside (if any).
        size_t present = 0;
        const PackageSection* cut = nullptr;
        for (const PackageSection& s : full.sections) {
            if (s.offset + s.stored_size <= available) {
                ++present;
            } else {
                if (s.offset < available) cut = &s;
                break;
            }
        }
        if (cut) {
            EXPECT_THAT(
                decode_error(prefix),
                HasSubstr(fmt::format("mat.btfpkg: section '{}' is truncated: {} of {} "
                                      "bytes present",
                                      cut->name, available - cut->offset, cut->stored_size)));
            continue;
        }
        const Package p = decode_package(prefix, "mat.btfpkg");
        EXPECT_EQ(p.declared_sections, full.declared_sections);
        EXPECT_EQ(p.file_bytes, length);
        ASSERT_EQ(p.sections.size(), present);
        EXPECT_EQ(p.complete(), length == bytes.size());
        for (size_t i = 0; i < present; ++i) EXPECT_EQ(p.sections[i].data, full.sections[i].data);
        if (present < full.sections.size()) {
            EXPECT_EQ(p.find(full.sections[present].name), nullptr);
            if (present > 0) {
                EXPECT_NE(p.find(full.sections[present - 1].name), nullptr);
            }
        }
    }
}

TEST(Package, PrefixesRaw) {
    Package p;
    p.header = {{"codec", "test"}};
    p.sections.push_back(section("a", random_bytes(40, 1)));
    p.sections.push_back(section("b", {}));
    p.sections.push_back(section("c", random_bytes(25, 2)));
    p.sections.push_back(section("d", random_bytes(1, 3)));
    check_prefixes(encode_package(p, {.zstd_level = 0}));
}

TEST(Package, PrefixesZstd) {
    Package p = sample_package();
    const Bytes bytes = encode_package(p, {.zstd_level = 3});
    check_prefixes(bytes);
    // The boundary prefixes, explicitly: each has one more section than the one before.
    const size_t start = data_start(bytes);
    for (size_t k = 0; k < p.sections.size(); ++k) {
        const size_t length = start + p.sections[k].offset;
        const Package q = decode_package(Bytes(bytes.begin(), bytes.begin() + long(length)), "x");
        EXPECT_FALSE(q.complete());
        EXPECT_EQ(q.declared_sections, 4);
        // The empty section 2 ends where section 3 starts: both cuts hold sections 0 to 2.
        EXPECT_EQ(q.sections.size(), k >= 2 ? 3u : k);
    }
}

TEST(Package, TruncatedHeaderMessages) {
    Package p = sample_package();
    const Bytes bytes = encode_package(p);
    EXPECT_EQ(decode_error({}),
              "mat.btfpkg: truncated in the header: 0 of the 24 preamble bytes present");
    EXPECT_EQ(decode_error(Bytes(bytes.begin(), bytes.begin() + 5)),
              "mat.btfpkg: truncated in the header: 5 of the 24 preamble bytes present");
    const uint32_t h = u32_at(bytes, 12);
    EXPECT_EQ(decode_error(Bytes(bytes.begin(), bytes.begin() + 24 + 10)),
              fmt::format("mat.btfpkg: truncated in the header: 10 of its {} JSON bytes present "
                          "(from byte 24)",
                          h));
}

TEST(Package, FlippedSectionByteNamesTheSection) {
    Package p = sample_package();
    const Bytes bytes = encode_package(p);
    const size_t start = data_start(bytes);
    for (const PackageSection& s : p.sections) {
        if (s.stored_size == 0) continue;
        for (uint64_t at : {uint64_t{0}, s.stored_size / 2, s.stored_size - 1}) {
            Bytes damaged = bytes;
            damaged[start + s.offset + at] ^= 0x10;
            EXPECT_THAT(
                decode_error(damaged),
                HasSubstr(fmt::format("mat.btfpkg: checksum mismatch in section '{}'", s.name)));
        }
    }
}

TEST(Package, FlippedHeaderByte) {
    Package p = sample_package();
    const Bytes bytes = encode_package(p);
    for (size_t at : {size_t{16}, size_t{23}, size_t{24}, size_t{60}, data_start(bytes) - 1}) {
        Bytes damaged = bytes;
        damaged[at] ^= 0x01;
        EXPECT_THAT(decode_error(damaged), HasSubstr("mat.btfpkg: header checksum mismatch"))
            << "byte " << at;
    }
}

TEST(Package, BadMagicVersionAndLength) {
    Package p = sample_package();
    const Bytes bytes = encode_package(p);
    for (size_t at = 0; at < 8; ++at) {
        Bytes damaged = bytes;
        damaged[at] ^= 0x20;
        EXPECT_EQ(decode_error(damaged), "mat.btfpkg: not a btfkit package (bad magic)");
    }
    EXPECT_EQ(decode_error(Bytes{'P', 'K', 3, 4}), "mat.btfpkg: not a btfkit package (bad magic)");

    Bytes v2 = bytes;
    v2[8] = 2;
    EXPECT_EQ(decode_error(v2), "mat.btfpkg: unsupported package version 2 (this btfkit reads 1)");

    Bytes huge = bytes;
    huge[15] = 0x10;  // header length 2^28 + ...
    EXPECT_THAT(decode_error(huge), HasSubstr("mat.btfpkg: byte 12: header length"));
    EXPECT_THAT(decode_error(huge), HasSubstr("exceeds the limit"));
}

TEST(Package, TrailingBytes) {
    Package p = sample_package();
    Bytes bytes = encode_package(p);
    const size_t end = bytes.size();
    bytes.insert(bytes.end(), {0, 0, 0});
    EXPECT_EQ(
        decode_error(bytes),
        fmt::format("mat.btfpkg: 3 trailing bytes after the last section (from byte {})", end));
    const Bytes empty = build(R"({"format":"btfpkg","sections":[],"version":1})", {9});
    EXPECT_THAT(decode_error(empty), HasSubstr("1 trailing bytes after the last section"));
    const Package none =
        decode_package(build(R"({"format":"btfpkg","sections":[],"version":1})", {}), "x");
    EXPECT_TRUE(none.complete());
    EXPECT_EQ(none.declared_sections, 0);
}

TEST(Package, InconsistentOrDamagedHeader) {
    Package p;
    p.header = {{"codec", "test"}};
    p.sections.push_back(section("a", random_bytes(10, 1)));
    p.sections.push_back(section("b", random_bytes(20, 2)));
    Bytes c = random_bytes(3000, 3);
    std::fill(c.begin() + 1500, c.end(), 0);
    p.sections.push_back(section("c", c));
    const Bytes bytes = encode_package(p);
    ASSERT_EQ(p.sections[2].coding, SectionCoding::kZstd);
    ASSERT_GT(p.sections[2].stored_size, ZSTD_compressBound(0));
    ASSERT_NO_THROW(decode_package(rebuild(bytes, [](json&) {}), "x"));

    const auto expect = [&](auto edit, const std::string& message) {
        EXPECT_THAT(decode_error(rebuild(bytes, edit)), HasSubstr("mat.btfpkg: " + message));
    };
    expect([](json& h) { h["sections"][1]["offset"] = 11; },
           "inconsistent header: section 1 ('b') starts at offset 11 but the section before it "
           "ends at 10");
    expect([](json& h) { h["sections"][0]["offset"] = 1; },
           "inconsistent header: section 0 ('a') starts at offset 1 but the header ends at 0");
    expect([](json& h) { h["sections"][1]["name"] = "a"; },
           "inconsistent header: two sections are named 'a'");
    expect([](json& h) { h["sections"][0]["raw_size"] = 11; },
           "inconsistent header: raw section 'a' stores 10 bytes but declares 11 decoded bytes");
    expect([](json& h) { h["sections"][2]["raw_size"] = uint64_t{1} << 40; },
           "section 'c' needs 1099511627776 bytes, over the limit of 4 GiB (raise it with "
           "--max-alloc or BTF_MAX_ALLOC)");
    expect([](json& h) { h["sections"][2]["raw_size"] = 0; },
           "inconsistent header: zstd section 'c' stores");
    expect([](json& h) { h["sections"][2]["size"] = 0; },
           "inconsistent header: zstd section 'c' declares 3000 decoded bytes, more than its 0 "
           "stored bytes can hold");
    EXPECT_THAT(decode_error(rebuild(bytes, [](json& h) { h["sections"][2]["raw_size"] = 2999; })),
                HasSubstr("mat.btfpkg: section 'c' (byte " +
                          std::to_string(data_start(bytes) + p.sections[2].offset) +
                          "): zstd frame holds 3000 bytes but the header declares 2999"));
    // A cut zstd frame with a matching checksum: zstd itself finds the damage.
    Bytes cut = bytes;
    cut.pop_back();
    const uint64_t cut_checksum = XXH64(cut.data() + data_start(cut) + p.sections[2].offset,
                                        p.sections[2].stored_size - 1, 0);
    EXPECT_THAT(
        decode_error(rebuild(cut,
                             [&](json& h) {
                                 h["sections"][2]["size"] = p.sections[2].stored_size - 1;
                                 h["sections"][2]["xxh64"] = fmt::format("{:016x}", cut_checksum);
                             })),
        HasSubstr("section 'c' (byte " + std::to_string(data_start(bytes) + p.sections[2].offset) +
                  "): not a zstd frame: "));
    expect([](json& h) { h["sections"][0]["coding"] = "lz4"; },
           "header: section 'a' has coding \"lz4\", expected \"raw\" or \"zstd\"");
    expect([](json& h) { h["sections"][0]["xxh64"] = "ABCDEF0123456789"; },
           "header: section 'a' field 'xxh64' must be 16 lowercase hex digits");
    expect([](json& h) { h["sections"][0]["xxh64"] = 12; },
           "header: section 'a' field 'xxh64' must be 16 lowercase hex digits");
    expect([](json& h) { h["sections"][1]["size"] = -20; },
           "header: section 1 field 'size' must be a non-negative integer, not -20");
    expect([](json& h) { h["sections"][1]["offset"] = 10.0; },
           "header: section 1 field 'offset' must be a non-negative integer, not 10.0");
    expect([](json& h) { h["sections"][1].erase("raw_size"); },
           "header: section 1 has no field 'raw_size'");
    expect([](json& h) { h["sections"][1]["extra"] = true; },
           "header: section 1 has an unknown field 'extra'");
    expect([](json& h) { h["sections"][1]["name"] = ""; },
           "header: section 1 field 'name' must be a non-empty string");
    expect([](json& h) { h["sections"][1] = 5; }, "header: section 1 is a JSON number");
    expect([](json& h) { h["sections"] = json::object(); },
           "header field 'sections' must be an array, not object");
    expect([](json& h) { h.erase("sections"); }, "header field 'sections' is missing");
    expect([](json& h) { h["format"] = "btf"; },
           "header field 'format' is \"btf\", expected \"btfpkg\"");
    expect([](json& h) { h.erase("format"); }, "header field 'format' is missing");
    expect([](json& h) { h["version"] = 2; },
           "inconsistent header: field 'version' is 2 but the preamble says 1");
    expect([](json& h) { h.erase("version"); }, "header field 'version' is missing");
    expect([](json& h) { h = json::array(); }, "header is a JSON array, not an object");

    EXPECT_THAT(decode_error(build("{\"format\": ", {})),
                HasSubstr("mat.btfpkg: header (byte 24) is not valid JSON: "));
}

TEST(Package, CodecFindAndAt) {
    Package p = sample_package();
    const Package q = decode_package(encode_package(p), "x");
    EXPECT_EQ(q.codec(), "test");
    ASSERT_NE(q.find("noise"), nullptr);
    EXPECT_EQ(q.find("noise")->data, random_bytes(300, 7));
    EXPECT_EQ(q.find("missing"), nullptr);
    EXPECT_EQ(&q.at("zeros"), q.find("zeros"));
    EXPECT_EQ(error_of([&] { q.at("missing"); }),
              "test package: no section 'missing' (4 of 4 declared sections present)");

    Package no_codec;
    EXPECT_THAT(error_of([&] { no_codec.codec(); }), HasSubstr("no 'codec' field"));
    no_codec.header["codec"] = 3;
    EXPECT_THAT(error_of([&] { no_codec.codec(); }), HasSubstr("'codec' must be a string"));
}

TEST(Package, EncoderRefusesBadInput) {
    Package twice;
    twice.sections.push_back(section("a", {1}));
    twice.sections.push_back(section("a", {2}));
    EXPECT_THAT(error_of([&] { encode_package(twice); }), HasSubstr("two sections are named 'a'"));
    Package unnamed;
    unnamed.sections.push_back(section("", {1}));
    EXPECT_THAT(error_of([&] { encode_package(unnamed); }), HasSubstr("empty name"));
    Package not_object;
    not_object.header = json::array();
    EXPECT_THAT(error_of([&] { encode_package(not_object); }), HasSubstr("must be a JSON object"));
    Package bad_text;
    bad_text.header["codec"] = std::string("\xff\xfe");  // not UTF-8
    EXPECT_THAT(error_of([&] { encode_package(bad_text); }),
                HasSubstr("package: package header cannot be written as JSON"));
    Package fine = sample_package();
    EXPECT_THAT(error_of([&] { encode_package(fine, {.zstd_level = 23}); }),
                HasSubstr("zstd level 23 is out of range"));
}

TEST(Package, WriteReadAndProbe) {
    const TempFolder dir("pkg");
    const fs::path path = dir.path() / "mat.btfpkg";
    Package p = sample_package();
    Package copy = sample_package();
    write_package(path, p);
    EXPECT_EQ(file_bytes(path), encode_package(copy));
    EXPECT_EQ(p.file_bytes, fs::file_size(path));
    EXPECT_TRUE(probe_package(path));

    const Package q = read_package(path);
    EXPECT_TRUE(q.complete());
    EXPECT_EQ(q.at("means").data, patterned_bytes(5000));

    // Only the package is left in the folder (no temporary files).
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);

    // A damaged file: the error names the path.
    Bytes bytes = file_bytes(path);
    bytes.resize(bytes.size() - 1);
    const fs::path cut = dir.path() / "cut.btfpkg";
    std::ofstream(cut, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    EXPECT_THAT(error_of([&] { read_package(cut); }),
                HasSubstr(cut.string() + ": section 'zeros' is truncated"));

    const fs::path other = dir.path() / "other.bin";
    std::ofstream(other) << "not a package at all";
    EXPECT_FALSE(probe_package(other));
    EXPECT_FALSE(probe_package(dir.path() / "none.btfpkg"));
    EXPECT_THAT(error_of([&] { read_package(other); }),
                HasSubstr(other.string() + ": not a btfkit package (bad magic)"));
    EXPECT_THAT(error_of([&] { read_package(dir.path() / "none.btfpkg"); }),
                HasSubstr("none.btfpkg: no such file"));
    EXPECT_THAT(error_of([&] { read_package(dir.path()); }), HasSubstr(": not a file"));
}

TEST(Package, WriteIsAtomic) {
    const TempFolder dir("pkg");
    Package p = sample_package();
    const fs::path missing = dir.path() / "missing" / "mat.btfpkg";
    EXPECT_THAT(error_of([&] { write_package(missing, p); }), HasSubstr("does not exist"));
    EXPECT_FALSE(fs::exists(dir.path() / "missing"));
    EXPECT_TRUE(fs::is_empty(dir.path()));

    // A failed encode leaves an existing file as it was and no temporary behind.
    const fs::path path = dir.path() / "mat.btfpkg";
    write_package(path, p);
    const Bytes before = file_bytes(path);
    Package bad = sample_package();
    bad.sections.push_back(section("means", {1}));
    EXPECT_THAT(error_of([&] { write_package(path, bad); }),
                HasSubstr(path.string() + ": two sections are named 'means'"));
    EXPECT_EQ(file_bytes(path), before);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);

    // Cancelling in the middle leaves the old file too.
    Progress cancelled;
    cancelled.cancel();
    Package other = sample_package();
    other.sections.pop_back();
    EXPECT_THROW(write_package(path, other, {}, cancelled), Cancelled);
    EXPECT_EQ(file_bytes(path), before);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

}  // namespace
}  // namespace btf
