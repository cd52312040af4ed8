// SPDX-License-Identifier: MIT
#include "btf/io/package.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <set>
#include <system_error>

#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

namespace btf {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr uint8_t kMagic[8] = {0x89, 'B', 'T', 'F', 'P', 'K', 'G', '\n'};
/// Section entry fields, in the order nlohmann::json writes them (alphabetical).
constexpr const char* kSectionFields[] = {"coding", "name", "offset", "raw_size", "size", "xxh64"};

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

void put_u64(std::vector<uint8_t>& out, uint64_t v) {
    for (int i = 0; i < 8; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

uint32_t get_u32(const uint8_t* p) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t{p[i]} << (8 * i);
    return v;
}

uint64_t get_u64(const uint8_t* p) {
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= uint64_t{p[i]} << (8 * i);
    return v;
}

uint64_t xxh64(const uint8_t* data, size_t size) {
    return XXH64(data, size, 0);
}

std::string hex64(uint64_t v) {
    return fmt::format("{:016x}", v);
}

std::optional<uint64_t> parse_hex64(const std::string& s) {
    if (s.size() != 16) return std::nullopt;
    uint64_t v = 0;
    for (char c : s) {
        int digit;
        if (c >= '0' && c <= '9') {
            digit = c - '0';
        } else if (c >= 'a' && c <= 'f') {
            digit = c - 'a' + 10;
        } else {
            return std::nullopt;
        }
        v = (v << 4) | uint64_t(digit);
    }
    return v;
}

const char* coding_name(SectionCoding coding) {
    return coding == SectionCoding::kZstd ? "zstd" : "raw";
}

/// A section's stored form: the zstd frame when it was compressed, else the decoded bytes
/// themselves (not copied).
struct Stored {
    std::vector<uint8_t> compressed;
    const std::vector<uint8_t>* bytes = nullptr;
};

/// Everything encode_package() and write_package() share: compresses the sections, fills in
/// their storage fields and the header, and returns the preamble + JSON header bytes. The file
/// is that followed by each section's stored bytes.
std::vector<uint8_t> prepare(Package& package, const PackageWriteOptions& options,
                             std::vector<Stored>& stored, const std::string& what,
                             Progress& progress) {
    if (!package.header.is_object())
        fail("{}: package header must be a JSON object, not {}", what, package.header.type_name());
    if (options.zstd_level < 0 || options.zstd_level > ZSTD_maxCLevel())
        fail("{}: zstd level {} is out of range (0 stores sections raw; 1..{} compress)", what,
             options.zstd_level, ZSTD_maxCLevel());
    std::set<std::string_view> names;
    for (const PackageSection& s : package.sections) {
        if (s.name.empty()) fail("{}: a section has an empty name", what);
        if (!names.insert(s.name).second)
            fail("{}: two sections are named '{}' (names must be unique)", what, s.name);
        // The reader's limit on a decoded section (util/limits.h): what is written can be read
        // under the same limits.
        check_alloc(s.data.size(), what, fmt::format("section '{}'", s.name));
    }

    const int64_t n = static_cast<int64_t>(package.sections.size());
    stored.assign(size_t(n), Stored{});
    progress.begin("compressing package sections", uint64_t(n));
    // Each section is compressed on its own, single-threaded, so the bytes do not depend on the
    // number of threads.
    parallel_for(0, n, [&](int64_t i) {
        PackageSection& s = package.sections[size_t(i)];
        Stored& out = stored[size_t(i)];
        out.bytes = &s.data;
        s.coding = SectionCoding::kRaw;
        if (options.zstd_level > 0 && !s.keep_raw && !s.data.empty()) {
            std::vector<uint8_t> frame(ZSTD_compressBound(s.data.size()));
            const size_t size = ZSTD_compress(frame.data(), frame.size(), s.data.data(),
                                              s.data.size(), options.zstd_level);
            if (ZSTD_isError(size))
                fail("{}: section '{}': zstd compression failed: {}", what, s.name,
                     ZSTD_getErrorName(size));
            if (size < s.data.size()) {
                frame.resize(size);
                frame.shrink_to_fit();
                out.compressed = std::move(frame);
                out.bytes = &out.compressed;
                s.coding = SectionCoding::kZstd;
            }
        }
        s.stored_size = out.bytes->size();
        s.checksum = xxh64(out.bytes->data(), out.bytes->size());
        progress.advance();
    });
    progress.finish();

    json table = json::array();
    uint64_t offset = 0;
    for (PackageSection& s : package.sections) {
        s.offset = offset;
        offset += s.stored_size;
        table.push_back({{"name", s.name},
                         {"offset", s.offset},
                         {"size", s.stored_size},
                         {"raw_size", uint64_t(s.data.size())},
                         {"coding", coding_name(s.coding)},
                         {"xxh64", hex64(s.checksum)}});
    }
    package.header["format"] = "btfpkg";
    package.header["version"] = kPackageVersion;
    package.header["sections"] = std::move(table);
    package.header["writer"] = options.writer;
    package.declared_sections = static_cast<int>(package.sections.size());

    std::string text;
    try {
        text = package.header.dump();
    } catch (const json::exception& e) {
        fail("{}: package header cannot be written as JSON: {}", what, e.what());
    }
    if (text.size() > kMaxPackageHeader)
        fail("{}: package header is {} bytes, more than the limit of {}", what, text.size(),
             kMaxPackageHeader);
    std::vector<uint8_t> head(std::begin(kMagic), std::end(kMagic));
    head.reserve(kPackagePreamble + text.size());
    put_u32(head, kPackageVersion);
    put_u32(head, static_cast<uint32_t>(text.size()));
    put_u64(head, xxh64(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
    head.insert(head.end(), text.begin(), text.end());
    package.file_bytes = head.size() + offset;
    return head;
}

/// A section table entry as read from the header, checked for types and sanity.
struct Entry {
    std::string name;
    uint64_t offset = 0, size = 0, raw_size = 0, checksum = 0;
    SectionCoding coding = SectionCoding::kRaw;
};

uint64_t unsigned_field(const json& entry, const char* field, int index, const std::string& what) {
    const json& v = entry.at(field);
    if (!v.is_number_unsigned())
        fail("{}: header: section {} field '{}' must be a non-negative integer, not {}", what,
             index, field, v.dump());
    return v.get<uint64_t>();
}

std::vector<Entry> read_table(const json& header, uint32_t version, const std::string& what) {
    if (!header.is_object())
        fail("{}: header is a JSON {}, not an object", what, header.type_name());
    const auto format = header.find("format");
    if (format == header.end()) fail("{}: header field 'format' is missing", what);
    if (!format->is_string() || format->get<std::string>() != "btfpkg")
        fail("{}: header field 'format' is {}, expected \"btfpkg\"", what, format->dump());
    const auto declared = header.find("version");
    if (declared == header.end()) fail("{}: header field 'version' is missing", what);
    if (!declared->is_number_unsigned() || declared->get<uint64_t>() != version)
        fail("{}: inconsistent header: field 'version' is {} but the preamble says {}", what,
             declared->dump(), version);
    const auto sections = header.find("sections");
    if (sections == header.end()) fail("{}: header field 'sections' is missing", what);
    if (!sections->is_array())
        fail("{}: header field 'sections' must be an array, not {}", what, sections->type_name());

    std::vector<Entry> table;
    std::set<std::string> names;
    uint64_t end = 0;
    int index = 0;
    for (const json& e : *sections) {
        if (!e.is_object())
            fail("{}: header: section {} is a JSON {}, not an object", what, index, e.type_name());
        for (const char* field : kSectionFields)
            if (!e.contains(field))
                fail("{}: header: section {} has no field '{}'", what, index, field);
        for (const auto& item : e.items()) {
            // Not a structured binding: clang before 16 cannot capture one in a lambda.
            const std::string& key = item.key();
            if (std::find_if(std::begin(kSectionFields), std::end(kSectionFields),
                             [&](const char* f) { return key == f; }) == std::end(kSectionFields))
                fail("{}: header: section {} has an unknown field '{}'", what, index, key);
        }
        Entry entry;
        const json& name = e.at("name");
        if (!name.is_string() || name.get<std::string>().empty())
            fail("{}: header: section {} field 'name' must be a non-empty string, not {}", what,
                 index, name.dump());
        entry.name = name.get<std::string>();
        entry.offset = unsigned_field(e, "offset", index, what);
        entry.size = unsigned_field(e, "size", index, what);
        entry.raw_size = unsigned_field(e, "raw_size", index, what);
        const json& coding = e.at("coding");
        if (coding == "raw") {
            entry.coding = SectionCoding::kRaw;
        } else if (coding == "zstd") {
            entry.coding = SectionCoding::kZstd;
        } else {
            fail("{}: header: section '{}' has coding {}, expected \"raw\" or \"zstd\"", what,
                 entry.name, coding.dump());
        }
        const json& hash = e.at("xxh64");
        const auto checksum =
            hash.is_string() ? parse_hex64(hash.get<std::string>()) : std::nullopt;
        if (!checksum)
            fail("{}: header: section '{}' field 'xxh64' must be 16 lowercase hex digits, not {}",
                 what, entry.name, hash.dump());
        entry.checksum = *checksum;

        if (!names.insert(entry.name).second)
            fail("{}: inconsistent header: two sections are named '{}'", what, entry.name);
        if (entry.offset != end)
            fail("{}: inconsistent header: section {} ('{}') starts at offset {} but {} ends at {}",
                 what, index, entry.name, entry.offset,
                 index == 0 ? std::string("the header") : "the section before it", end);
        check_alloc(entry.raw_size, what, fmt::format("section '{}'", entry.name));
        if (entry.coding == SectionCoding::kRaw && entry.size != entry.raw_size)
            fail(
                "{}: inconsistent header: raw section '{}' stores {} bytes but declares {} "
                "decoded bytes",
                what, entry.name, entry.size, entry.raw_size);
        if (entry.coding == SectionCoding::kZstd && entry.size > ZSTD_compressBound(entry.raw_size))
            fail(
                "{}: inconsistent header: zstd section '{}' stores {} bytes, more than zstd "
                "needs for {} decoded bytes",
                what, entry.name, entry.size, entry.raw_size);
        // A zstd block decodes to at most 128 KiB and takes at least 4 bytes (an RLE block), so
        // a frame of `size` bytes cannot hold more than size * 2^15 bytes.
        if (entry.coding == SectionCoding::kZstd &&
            entry.raw_size > checked_bytes(entry.size, uint64_t{1} << 15).value_or(UINT64_MAX))
            fail(
                "{}: inconsistent header: zstd section '{}' declares {} decoded bytes, more "
                "than its {} stored bytes can hold",
                what, entry.name, entry.raw_size, entry.size);
        end += entry.size;
        table.push_back(std::move(entry));
        ++index;
    }
    return table;
}

/// Checks and decodes one fully present section; returns an error message instead of throwing
/// so that parallel decoding reports the first bad section in file order.
std::optional<std::string> decode_section(const Entry& entry, const uint8_t* bytes,
                                          uint64_t file_offset, PackageSection& out,
                                          const std::string& what) {
    const uint64_t checksum = xxh64(bytes, entry.size);
    if (checksum != entry.checksum)
        return fmt::format(
            "{}: checksum mismatch in section '{}' (bytes {}..{}): stored {}, computed {}", what,
            entry.name, file_offset, file_offset + entry.size, hex64(entry.checksum),
            hex64(checksum));
    out.name = entry.name;
    out.coding = entry.coding;
    out.offset = entry.offset;
    out.stored_size = entry.size;
    out.checksum = entry.checksum;
    if (entry.coding == SectionCoding::kRaw) {
        out.data.assign(bytes, bytes + entry.size);
        return std::nullopt;
    }
    const size_t frame = ZSTD_findFrameCompressedSize(bytes, entry.size);
    if (ZSTD_isError(frame))
        return fmt::format("{}: section '{}' (byte {}): not a zstd frame: {}", what, entry.name,
                           file_offset, ZSTD_getErrorName(frame));
    if (frame != entry.size)
        return fmt::format(
            "{}: section '{}' (byte {}): zstd frame is {} bytes but the section "
            "stores {}",
            what, entry.name, file_offset, frame, entry.size);
    const unsigned long long content = ZSTD_getFrameContentSize(bytes, entry.size);
    if (content == ZSTD_CONTENTSIZE_UNKNOWN || content == ZSTD_CONTENTSIZE_ERROR)
        return fmt::format("{}: section '{}' (byte {}): zstd frame does not declare its size", what,
                           entry.name, file_offset);
    if (content != entry.raw_size)
        return fmt::format(
            "{}: section '{}' (byte {}): zstd frame holds {} bytes but the header "
            "declares {}",
            what, entry.name, file_offset, content, entry.raw_size);
    out.data.resize(entry.raw_size);
    const size_t size = ZSTD_decompress(out.data.data(), out.data.size(), bytes, entry.size);
    if (ZSTD_isError(size))
        return fmt::format("{}: section '{}' (byte {}): cannot decompress: {}", what, entry.name,
                           file_offset, ZSTD_getErrorName(size));
    if (size != entry.raw_size)
        return fmt::format("{}: section '{}' (byte {}): decompressed to {} bytes, expected {}",
                           what, entry.name, file_offset, size, entry.raw_size);
    return std::nullopt;
}

}  // namespace

const PackageSection* Package::find(std::string_view name) const {
    for (const PackageSection& s : sections)
        if (s.name == name) return &s;
    return nullptr;
}

const PackageSection& Package::at(std::string_view name) const {
    if (const PackageSection* s = find(name)) return *s;
    const auto codec = header.find("codec");
    fail("{} package: no section '{}' ({} of {} declared sections present)",
         codec != header.end() && codec->is_string() ? codec->get<std::string>() : "btfpkg", name,
         sections.size(), declared_sections);
}

std::string Package::codec() const {
    const auto codec = header.find("codec");
    if (codec == header.end()) fail("package: header has no 'codec' field");
    if (!codec->is_string())
        fail("package: header field 'codec' must be a string, not {}", codec->dump());
    return codec->get<std::string>();
}

std::vector<uint8_t> encode_package(Package& package, const PackageWriteOptions& options) {
    std::vector<Stored> stored;
    std::vector<uint8_t> bytes = prepare(package, options, stored, "package", Progress::none());
    bytes.reserve(package.file_bytes);
    for (const Stored& s : stored) bytes.insert(bytes.end(), s.bytes->begin(), s.bytes->end());
    return bytes;
}

void write_package(const fs::path& path, Package& package, const PackageWriteOptions& options,
                   Progress& progress) {
    const std::string name = path.string();
    AtomicOutput output(path);
    std::vector<Stored> stored;
    const std::vector<uint8_t> head = prepare(package, options, stored, name, progress);

    std::ofstream out(output.temp_path(), std::ios::binary | std::ios::trunc);
    if (!out) fail("{}: cannot open {} for writing", name, output.temp_path().string());
    const auto write = [&](const std::vector<uint8_t>& bytes) {
        out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
        if (!out) fail("{}: write error (disk full?)", name);
    };
    progress.begin("writing package", package.file_bytes);
    write(head);
    progress.advance(head.size());
    for (const Stored& s : stored) {
        write(*s.bytes);
        progress.advance(s.bytes->size());
    }
    out.close();
    if (!out) fail("{}: write error when closing (disk full?)", name);
    output.commit();
    progress.finish();
}

Package decode_package(std::span<const uint8_t> bytes, const std::string& what) {
    const uint64_t total = bytes.size();
    if (total > 0 && std::memcmp(bytes.data(), kMagic, std::min<size_t>(total, sizeof kMagic)) != 0)
        fail("{}: not a btfkit package (bad magic)", what);
    if (total < uint64_t(kPackagePreamble))
        fail("{}: truncated in the header: {} of the {} preamble bytes present", what, total,
             kPackagePreamble);
    const uint32_t version = get_u32(bytes.data() + 8);
    if (version != kPackageVersion)
        fail("{}: unsupported package version {} (this btfkit reads {})", what, version,
             kPackageVersion);
    const uint32_t header_size = get_u32(bytes.data() + 12);
    if (header_size > kMaxPackageHeader)
        fail("{}: byte 12: header length {} exceeds the limit of {} bytes", what, header_size,
             kMaxPackageHeader);
    if (total < uint64_t(kPackagePreamble) + header_size)
        fail("{}: truncated in the header: {} of its {} JSON bytes present (from byte {})", what,
             total - kPackagePreamble, header_size, kPackagePreamble);
    const uint8_t* text = bytes.data() + kPackagePreamble;
    const uint64_t header_checksum = get_u64(bytes.data() + 16);
    const uint64_t computed = xxh64(text, header_size);
    if (computed != header_checksum)
        fail("{}: header checksum mismatch (bytes {}..{}): stored {}, computed {}", what,
             kPackagePreamble, kPackagePreamble + header_size, hex64(header_checksum),
             hex64(computed));

    Package package;
    try {
        package.header = json::parse(text, text + header_size);
    } catch (const json::exception& e) {
        fail("{}: header (byte {}) is not valid JSON: {}", what, kPackagePreamble, e.what());
    }
    const std::vector<Entry> table = read_table(package.header, version, what);
    package.declared_sections = static_cast<int>(table.size());
    package.file_bytes = total;

    // Which sections are present: a clean prefix stops at a section boundary; anything else
    // short of the declared end is a truncation, anything past it does not belong there.
    const uint64_t data_start = kPackagePreamble + uint64_t(header_size);
    const uint64_t available = total - data_start;
    size_t present = 0;
    for (const Entry& e : table) {
        if (e.offset + e.size <= available) {
            ++present;
        } else if (e.offset == available) {
            break;
        } else {
            fail("{}: section '{}' is truncated: {} of {} bytes present (from byte {})", what,
                 e.name, available - e.offset, e.size, data_start + e.offset);
        }
    }
    if (present == table.size()) {
        const uint64_t end = table.empty() ? 0 : table.back().offset + table.back().size;
        if (available > end)
            fail("{}: {} trailing bytes after the last section (from byte {})", what,
                 available - end, data_start + end);
    }

    package.sections.resize(present);
    std::vector<std::optional<std::string>> errors(present);
    parallel_for(0, int64_t(present), [&](int64_t i) {
        const Entry& e = table[size_t(i)];
        errors[size_t(i)] =
            decode_section(e, bytes.data() + data_start + e.offset, data_start + e.offset,
                           package.sections[size_t(i)], what);
    });
    for (const auto& error : errors)
        if (error) throw Error(*error);
    return package;
}

Package read_package(const fs::path& path) {
    const std::string name = path.string();
    std::error_code ec;
    if (!fs::exists(path, ec)) fail("{}: no such file", name);
    if (!fs::is_regular_file(path, ec)) fail("{}: not a file", name);
    std::ifstream in(path, std::ios::binary);
    if (!in) fail("{}: cannot open for reading: {}", name, std::strerror(errno));
    const uint64_t size = fs::file_size(path, ec);
    if (ec) fail("{}: cannot read the file size: {}", name, ec.message());
    std::vector<uint8_t> bytes(size);
    in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size));
    if (uint64_t(in.gcount()) != size)
        fail("{}: read error after {} of {} bytes", name, in.gcount(), size);
    return decode_package(bytes, name);
}

bool probe_package(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    uint8_t head[sizeof kMagic];
    if (!in.read(reinterpret_cast<char*>(head), sizeof head)) return false;
    return std::memcmp(head, kMagic, sizeof kMagic) == 0;
}

}  // namespace btf
