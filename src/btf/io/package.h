// SPDX-License-Identifier: MIT
#pragma once
/// The `.btfpkg` package: btfkit's compressed material file (byte layout in docs/formats.md,
/// "btfkit package").
///
///     offset 0   8 bytes   magic 89 42 54 46 50 4B 47 0A  ("\x89BTFPKG\n")
///     offset 8   uint32 LE format version (kPackageVersion)
///     offset 12  uint32 LE H: length of the JSON header in bytes
///     offset 16  uint64 LE XXH64 (seed 0) of the JSON header bytes
///     offset 24  H bytes   JSON header (UTF-8)
///     24 + H     the sections' stored bytes, back to back in the order of header.sections
///
/// The header holds the codec, its parameters and whatever the codec needs to interpret the
/// sections, plus the section table: for each section its name, offset (relative to the end of
/// the JSON header), stored size, decoded size, coding ("raw" or "zstd") and the XXH64 of the
/// stored bytes as 16 hex digits. Sections come in streaming order, so any prefix that ends on a
/// section boundary is itself readable: read_package() returns the complete sections and marks
/// the package as a prefix; a codec opens it as a lower-quality material.

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "btf/util/error.h"
#include "btf/util/progress.h"
#include "btf/version.h"

namespace btf {

/// Current format version; a reader refuses any other.
constexpr uint32_t kPackageVersion = 1;
/// Size of the fixed part before the JSON header.
constexpr int kPackagePreamble = 24;
/// Largest JSON header a reader accepts (a sanity limit checked before allocating).
constexpr uint32_t kMaxPackageHeader = 64u << 20;

enum class SectionCoding { kRaw, kZstd };

struct PackageSection {
    std::string name;
    std::vector<uint8_t> data;  ///< decoded bytes
    /// Store the section raw whatever the zstd level, so that byte ranges of the file map to
    /// byte ranges of the data (readers fetch parts of it, e.g. the tiles of a BSVTF).
    bool keep_raw = false;
    // Storage, filled in by encode_package() and read_package():
    SectionCoding coding = SectionCoding::kRaw;
    uint64_t offset = 0;       ///< of the stored bytes, from the end of the JSON header
    uint64_t stored_size = 0;  ///< bytes in the file
    uint64_t checksum = 0;     ///< XXH64 of the stored bytes
};

struct Package {
    /// Codec-specific header fields; encode_package() adds "format", "version" and "sections".
    nlohmann::json header = nlohmann::json::object();
    std::vector<PackageSection> sections;  ///< in streaming order
    /// Sections the header declares; sections.size() is smaller for a prefix.
    int declared_sections = 0;
    /// File size in bytes (set by encode_package() and read_package()).
    uint64_t file_bytes = 0;

    bool complete() const { return static_cast<int>(sections.size()) == declared_sections; }
    /// The section named `name`, or nullptr if it is not (yet) present.
    const PackageSection* find(std::string_view name) const;
    /// Like find(), but throws btf::Error naming the package and the section when missing.
    const PackageSection& at(std::string_view name) const;
    /// The codec name from the header.
    std::string codec() const;
};

struct PackageWriteOptions {
    /// zstd level for every section (1..22); 0 stores sections raw. A section is also stored raw
    /// when zstd does not make it smaller.
    int zstd_level = 9;
    /// The header's "writer" field: the program that wrote the file (btfkit and its version).
    std::string writer = writer_name();
};

/// Serializes `package` (filling in each section's storage fields and file_bytes).
std::vector<uint8_t> encode_package(Package& package, const PackageWriteOptions& options = {});
/// encode_package() then an atomic write to `path`.
void write_package(const std::filesystem::path& path, Package& package,
                   const PackageWriteOptions& options = {}, Progress& progress = Progress::none());

/// Parses package bytes (a whole file or a prefix of one ending on a section boundary). `what`
/// names the data in errors (a file name). Throws btf::Error for a bad magic, an unknown
/// version, a damaged or inconsistent header, a checksum mismatch or a truncation inside the
/// header or a section.
Package decode_package(std::span<const uint8_t> bytes, const std::string& what);
/// Reads and decodes a package file.
Package read_package(const std::filesystem::path& path);
/// True if the file starts with the package magic.
bool probe_package(const std::filesystem::path& path);

/// Runs `read`, which interprets a package's header and sections for a codec, and gives its
/// errors the one-line form every codec uses: a JSON error becomes "WHAT: bad header: …", any
/// other btf::Error "WHAT: …" (unless it already starts with WHAT); cancellation passes through.
template <typename Read>
auto read_package_fields(const std::string& what, Read&& read) -> decltype(read()) {
    try {
        return read();
    } catch (const nlohmann::json::exception& e) {
        fail("{}: bad header: {}", what, e.what());
    } catch (const Cancelled&) {
        throw;
    } catch (const Error& e) {
        if (std::string_view(e.what()).starts_with(what)) throw;
        fail("{}: {}", what, e.what());
    }
}

}  // namespace btf
