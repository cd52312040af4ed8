// SPDX-License-Identifier: MIT
#pragma once
/// The material list of the streaming protocol (docs/protocol.md, `GET api/materials`): which
/// packages `btf serve` and `btf bundle` publish, under which ids, and where each package's
/// sections lie in its file. Only package headers are read (never the sections), so building a
/// catalog of large packages is fast and needs little memory.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace btf::stream {

/// Version of docs/protocol.md this code implements (the list's "protocol" field).
constexpr int kProtocolVersion = 1;
/// Longest material id the protocol allows.
constexpr int kMaxIdLength = 64;

/// One section of a package file: `offset` counts from the start of the file.
struct CatalogSection {
    std::string name;
    uint64_t offset = 0;
    uint64_t size = 0;
};

/// One published package.
struct CatalogEntry {
    std::string id;              ///< `[A-Za-z0-9_.-]{1,64}`, unique in its catalog
    std::string name;            ///< the file name without `.btfpkg`
    std::filesystem::path path;  ///< the package file (absolute, symbolic links resolved)
    std::string codec;           ///< the header's codec
    int width = 0, height = 0;   ///< texels
    int views = 0, lights = 0;   ///< sampling counts
    uint64_t bytes = 0;          ///< file size
    uint64_t header_bytes = 0;   ///< 24 + the JSON header's length: bytes before the sections
    std::vector<CatalogSection> sections;  ///< present sections in file order
    /// Modification time when the header was read; the server refuses to send a file that has
    /// changed since, because its list entry (sizes, section offsets) would no longer match it.
    std::filesystem::file_time_type modified;

    /// The list entry of `GET api/materials` ("stream" is null when `with_stream` is false, as
    /// in a static bundle).
    nlohmann::ordered_json to_json(bool with_stream) const;
};

/// Reads the header of the package at `path` and describes it (the id is left empty). Throws
/// btf::Error naming the file for a missing file, a damaged header, a header without the
/// extent and sampling fields, or a file that is cut inside a section or has trailing bytes.
CatalogEntry describe_package(const std::filesystem::path& path);

/// A material id derived from a file stem: characters outside `[A-Za-z0-9_.-]` become `_`, a
/// leading `.` becomes `_` (so an id is never a hidden file name or a dot segment of a URL),
/// and the result is cut to `max_length` characters; an empty stem gives "material".
std::string make_id(std::string_view stem, size_t max_length = kMaxIdLength);

/// True for a string the protocol accepts as an id.
bool valid_id(std::string_view id);

/// The published packages in a fixed order, with unique ids.
class Catalog {
  public:
    Catalog() = default;

    /// Builds a catalog from package files and folders (a folder contributes the `*.btfpkg`
    /// files directly inside it, by file name). The same file given twice is listed once;
    /// different files with the same id get `-2`, `-3`, … appended. Throws btf::Error naming
    /// the path for a missing input, a folder without packages or a damaged package.
    static Catalog build(const std::vector<std::filesystem::path>& inputs);

    /// Adds one package file and returns its entry (id assigned).
    const CatalogEntry& add(const std::filesystem::path& package);

    const std::vector<CatalogEntry>& entries() const { return m_entries; }
    size_t size() const { return m_entries.size(); }
    bool empty() const { return m_entries.empty(); }
    /// The entry with this id, or nullptr.
    const CatalogEntry* find(std::string_view id) const;

    /// The document of `GET api/materials`: {"protocol": 1, "materials": [...]}.
    nlohmann::ordered_json to_json(bool with_stream) const;

  private:
    std::vector<CatalogEntry> m_entries;
};

/// A self-contained HTML page that lists the catalog's materials as links to their packages
/// (`materials/<id>.btfpkg`, relative, so it works from `btf serve` and from a bundle). The
/// server and `btf bundle` use it as the start page when no viewer build is available; `note`
/// (plain text, escaped here) says why.
std::string index_page(const Catalog& catalog, std::string_view note, bool with_stream);

/// JSON text that never throws on invalid UTF-8 in names or request paths (bytes are replaced
/// with U+FFFD).
std::string dump_json(const nlohmann::ordered_json& value, int indent = -1);

}  // namespace btf::stream
