// SPDX-License-Identifier: MIT
#include "btf/stream/catalog.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <tuple>

#include "btf/io/package.h"
#include "btf/quality/plot.h"
#include "btf/stream/request.h"
#include "btf/util/error.h"
#include "btf/util/json_fields.h"
#include "btf/util/limits.h"

namespace btf::stream {

namespace fs = std::filesystem;

namespace {

uint32_t get_u32(const uint8_t* p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

bool id_char(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '.' || c == '-';
}

// Packages: `.btfpkg`, and `.bsvtf` (the BSVTF packages of `btf bsvtf`, docs/bsvtf.md).
bool has_package_extension(const fs::path& path) {
    const std::string ext = ascii_lower(path.extension().string());
    return ext == ".btfpkg" || ext == ".bsvtf";
}

// The file name without its package extension (other names are kept whole: the id then says
// which file it is).
std::string package_stem(const fs::path& path) {
    return has_package_extension(path) ? path.stem().string() : path.filename().string();
}

std::string size_text(uint64_t bytes) {
    const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
    double value = double(bytes);
    int u = 0;
    while (value >= 1024 && u < 4) value /= 1024, ++u;
    return u == 0 ? fmt::format("{} B", bytes) : fmt::format("{:.1f} {}", value, units[u]);
}

}  // namespace

std::string make_id(std::string_view stem, size_t max_length) {
    std::string id;
    for (const char c : stem) {
        if (id.size() == max_length) break;
        id += id_char(c) ? c : '_';
    }
    if (!id.empty() && id[0] == '.') id[0] = '_';
    if (id.empty()) id = std::string("material").substr(0, std::max<size_t>(max_length, 1));
    return id;
}

bool valid_id(std::string_view id) {
    return !id.empty() && id.size() <= size_t(kMaxIdLength) &&
           std::all_of(id.begin(), id.end(), id_char);
}

CatalogEntry describe_package(const fs::path& path) {
    const std::string what = path.string();
    std::error_code ec;
    if (!fs::exists(path, ec)) fail("{}: no such file", what);
    if (!fs::is_regular_file(path, ec)) fail("{}: not a file", what);
    CatalogEntry entry;
    entry.path = fs::canonical(path, ec);
    if (ec) fail("{}: cannot resolve the path: {}", what, ec.message());
    entry.name = package_stem(path);
    entry.bytes = fs::file_size(entry.path, ec);
    if (ec) fail("{}: cannot read the file size: {}", what, ec.message());
    entry.modified = fs::last_write_time(entry.path, ec);
    if (ec) fail("{}: cannot read the modification time: {}", what, ec.message());

    // Only the preamble and the JSON header are read; decode_package() checks them (magic,
    // version, length limit, checksum, section table) and reports a short file itself.
    std::ifstream in(entry.path, std::ios::binary);
    if (!in) fail("{}: cannot open for reading: {}", what, std::strerror(errno));
    uint64_t wanted = std::min<uint64_t>(entry.bytes, kPackagePreamble);
    std::vector<uint8_t> head(wanted);
    in.read(reinterpret_cast<char*>(head.data()), std::streamsize(head.size()));
    if (uint64_t(in.gcount()) != wanted)
        fail("{}: read error after {} of {} bytes", what, in.gcount(), wanted);
    if (wanted == uint64_t(kPackagePreamble)) {
        const uint32_t header_size = get_u32(head.data() + 12);
        if (header_size <= kMaxPackageHeader && std::memcmp(head.data(),
                                                            "\x89"
                                                            "BTFPKG\n",
                                                            8) == 0) {
            wanted = std::min<uint64_t>(entry.bytes, uint64_t(kPackagePreamble) + header_size);
            head.resize(wanted);
            in.read(reinterpret_cast<char*>(head.data()) + kPackagePreamble,
                    std::streamsize(wanted - kPackagePreamble));
            if (uint64_t(in.gcount()) != wanted - kPackagePreamble)
                fail("{}: read error after {} of {} bytes", what, kPackagePreamble + in.gcount(),
                     wanted);
        }
    }
    const Package package = decode_package(head, what);
    entry.header_bytes = head.size();

    read_package_fields(what, [&] {
        entry.codec = package.codec();
        // A BSVTF package describes its material in the header of the fmf package it was made
        // from (bsvtf/file.h).
        const nlohmann::json& material =
            entry.codec == "bsvtf" ? package.header.at("source") : package.header;
        std::tie(entry.width, entry.height) = json_fields::extent(material);
        entry.views = int(material.at("views").at("theta").size());
        entry.lights = int(material.at("lights").at("theta").size());
        check(entry.views > 0 && entry.lights > 0, "sampling of {} views x {} lights is empty",
              entry.views, entry.lights);
        // The reader has validated the table: offsets are contiguous from 0.
        const uint64_t available = entry.bytes - entry.header_bytes;
        for (const nlohmann::json& s : package.header.at("sections")) {
            const uint64_t offset = s.at("offset").get<uint64_t>();
            const uint64_t size = s.at("size").get<uint64_t>();
            const std::string name = s.at("name").get<std::string>();
            if (offset + size > available) {
                // A file cut exactly at a section boundary is a valid, lower-quality package.
                if (offset == available) break;
                fail("section '{}' is truncated: {} of {} bytes present (from byte {})", name,
                     available - offset, size, entry.header_bytes + offset);
            }
            entry.sections.push_back({name, entry.header_bytes + offset, size});
        }
        const uint64_t end = entry.sections.empty()
                                 ? entry.header_bytes
                                 : entry.sections.back().offset + entry.sections.back().size;
        check(end == entry.bytes, "{} trailing bytes after the last section (from byte {})",
              entry.bytes - end, end);
    });
    return entry;
}

nlohmann::ordered_json CatalogEntry::to_json(bool with_stream) const {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const CatalogSection& s : sections)
        list.push_back({{"name", s.name}, {"offset", s.offset}, {"size", s.size}});
    nlohmann::ordered_json j;
    j["id"] = id;
    j["name"] = name;
    j["codec"] = codec;
    j["width"] = width;
    j["height"] = height;
    j["views"] = views;
    j["lights"] = lights;
    j["bytes"] = bytes;
    j["header_bytes"] = header_bytes;
    j["sections"] = std::move(list);
    j["package"] = "materials/" + id + ".btfpkg";
    j["stream"] = with_stream ? nlohmann::ordered_json("stream/" + id) : nlohmann::ordered_json();
    return j;
}

const CatalogEntry& Catalog::add(const fs::path& package) {
    CatalogEntry entry = describe_package(package);
    for (const CatalogEntry& e : m_entries)
        if (e.path == entry.path) return e;
    // Ids are compared without case: a bundle's materials/<id>.btfpkg files must stay distinct
    // on case-insensitive file systems too.
    const auto taken = [&](const std::string& id) {
        const std::string key = ascii_lower(id);
        return std::any_of(m_entries.begin(), m_entries.end(),
                           [&](const CatalogEntry& e) { return ascii_lower(e.id) == key; });
    };
    entry.id = make_id(entry.name);
    for (int n = 2; taken(entry.id); ++n) {
        const std::string suffix = fmt::format("-{}", n);
        entry.id = make_id(entry.name, kMaxIdLength - suffix.size()) + suffix;
    }
    m_entries.push_back(std::move(entry));
    return m_entries.back();
}

Catalog Catalog::build(const std::vector<fs::path>& inputs) {
    Catalog catalog;
    for (const fs::path& input : inputs) {
        std::error_code ec;
        if (!fs::exists(input, ec)) fail("{}: no such file or folder", input.string());
        if (!fs::is_directory(input, ec)) {
            catalog.add(input);
            continue;
        }
        std::vector<fs::path> packages;
        for (const fs::directory_entry& e : fs::directory_iterator(input, ec))
            if (e.is_regular_file(ec) && has_package_extension(e.path()))
                packages.push_back(e.path());
        if (ec) fail("{}: cannot list the folder: {}", input.string(), ec.message());
        if (packages.empty())
            fail("{}: no *.btfpkg or *.bsvtf packages in this folder", input.string());
        std::sort(packages.begin(), packages.end());
        for (const fs::path& p : packages) catalog.add(p);
    }
    return catalog;
}

const CatalogEntry* Catalog::find(std::string_view id) const {
    for (const CatalogEntry& e : m_entries)
        if (e.id == id) return &e;
    return nullptr;
}

nlohmann::ordered_json Catalog::to_json(bool with_stream) const {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const CatalogEntry& e : m_entries) list.push_back(e.to_json(with_stream));
    return {{"protocol", kProtocolVersion}, {"materials", std::move(list)}};
}

std::string dump_json(const nlohmann::ordered_json& value, int indent) {
    return value.dump(indent, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

std::string index_page(const Catalog& catalog, std::string_view note, bool with_stream) {
    std::string rows;
    for (const CatalogEntry& e : catalog.entries()) {
        const std::string href = "materials/" + e.id + ".btfpkg";
        rows += fmt::format(
            "<tr><td><a href=\"{0}\" download>{1}</a></td><td>{2}</td><td>{3}&times;{4}</td>"
            "<td>{5}&times;{6}</td><td>{7}</td><td class=\"n\">{8}</td></tr>\n",
            quality::xml_escape(href), quality::xml_escape(e.name), quality::xml_escape(e.codec),
            e.width, e.height, e.views, e.lights, e.sections.size(), size_text(e.bytes));
    }
    if (rows.empty()) rows = "<tr><td colspan=\"6\">no materials</td></tr>\n";
    const std::string count =
        fmt::format("{} material{}", catalog.size(), catalog.size() == 1 ? "" : "s");
    const std::string stream_line =
        with_stream ? "<li><code>stream/&lt;id&gt;</code>: WebSocket stream of a package</li>\n"
                    : "";
    return fmt::format(
        R"(<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>btfkit: {0}</title>
<style>
body {{ font: 15px/1.5 system-ui, sans-serif; margin: 2em auto; max-width: 56em; padding: 0 1em; }}
table {{ border-collapse: collapse; width: 100%; }}
th, td {{ border-bottom: 1px solid #ccc; padding: 0.3em 0.6em; text-align: left; }}
td.n {{ text-align: right; white-space: nowrap; }}
.note {{ background: #fff4d6; border: 1px solid #e0c060; padding: 0.6em 1em; }}
</style>
</head>
<body>
<h1>btfkit materials</h1>
<p class="note">{1}</p>
<p>{0}, compressed as btfkit packages (<code>.btfpkg</code>). Each link downloads the package;
<code>btf info</code>, <code>btf eval</code> and <code>btf render</code> read it.</p>
<table>
<tr><th>material</th><th>codec</th><th>texels</th><th>views&times;lights</th><th>sections</th><th>size</th></tr>
{2}</table>
<h2>Endpoints</h2>
<ul>
<li><a href="api/materials"><code>api/materials</code></a>: the material list (JSON)</li>
<li><code>materials/&lt;id&gt;.btfpkg</code>: a package, with byte-range requests</li>
{3}</ul>
</body>
</html>
)",
        count, quality::xml_escape(note), rows, stream_line);
}

}  // namespace btf::stream
