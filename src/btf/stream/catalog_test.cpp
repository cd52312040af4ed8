// SPDX-License-Identifier: MIT
// The material list (ids, section tables read from package headers, errors) and static bundles.

#include "btf/stream/catalog.h"

#include <gtest/gtest.h>

#include <fstream>

#include "btf/io/package.h"
#include "btf/stream/bundle.h"
#include "btf/testing/support.h"

namespace btf::stream {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using test::error_of;
using test::TempFolder;

using test::read_file;
using test::write_file;

// A package of raw sections of the given sizes, with the extent and sampling fields every codec
// writes (2 views, 3 lights, 8×6 texels).
void make_package(const fs::path& path, const std::vector<size_t>& sizes) {
    Package package;
    package.header = {{"codec", "test"},
                      {"width", 8},
                      {"height", 6},
                      {"views", {{"theta", {0.0, 0.5}}, {"phi", {0.0, 0.0}}}},
                      {"lights", {{"theta", {0.0, 0.2, 0.4}}, {"phi", {0.0, 1.0, 2.0}}}}};
    for (size_t i = 0; i < sizes.size(); ++i) {
        PackageSection s;
        s.name = fmt::format("s{}", i);
        s.data.assign(sizes[i], uint8_t(i + 1));
        package.sections.push_back(std::move(s));
    }
    PackageWriteOptions options;
    options.zstd_level = 0;
    write_package(path, package, options);
}

TEST(Catalog, Ids) {
    EXPECT_EQ(make_id("woven_fabric"), "woven_fabric");
    EXPECT_EQ(make_id("my material (v1.2)"), "my_material__v1.2_");
    EXPECT_EQ(make_id(".hidden"), "_hidden");
    EXPECT_EQ(make_id(""), "material");
    EXPECT_EQ(make_id(std::string(100, 'a')), std::string(64, 'a'));
    EXPECT_TRUE(valid_id("a-b_c.d"));
    EXPECT_FALSE(valid_id(""));
    EXPECT_FALSE(valid_id("a/b"));
    EXPECT_FALSE(valid_id(std::string(65, 'a')));
}

TEST(Catalog, DescribesSectionsWithFileOffsets) {
    TempFolder dir;
    const fs::path path = dir.path() / "tiles.btfpkg";
    make_package(path, {100, 0, 70000, 5});
    const CatalogEntry e = describe_package(path);
    const Package package = read_package(path);
    const std::string file = read_file(path);
    uint32_t header_length;
    std::memcpy(&header_length, file.data() + 12, 4);

    EXPECT_EQ(e.name, "tiles");
    EXPECT_EQ(e.codec, "test");
    EXPECT_EQ(e.width, 8);
    EXPECT_EQ(e.height, 6);
    EXPECT_EQ(e.views, 2);
    EXPECT_EQ(e.lights, 3);
    EXPECT_EQ(e.bytes, file.size());
    EXPECT_EQ(e.header_bytes, 24u + header_length);
    EXPECT_EQ(e.path, fs::canonical(path));
    ASSERT_EQ(e.sections.size(), 4u);
    for (size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(e.sections[i].name, package.sections[i].name);
        EXPECT_EQ(e.sections[i].offset, e.header_bytes + package.sections[i].offset);
        EXPECT_EQ(e.sections[i].size, package.sections[i].stored_size);
        // The offset points at the section's bytes.
        if (e.sections[i].size > 0) {
            EXPECT_EQ(uint8_t(file[e.sections[i].offset]), i + 1);
        }
    }
    EXPECT_EQ(e.sections.back().offset + e.sections.back().size, e.bytes);
}

TEST(Catalog, PrefixFilesListTheirPresentSections) {
    TempFolder dir;
    const fs::path full = dir.path() / "full.btfpkg";
    make_package(full, {100, 200, 300});
    const std::string bytes = read_file(full);
    const CatalogEntry whole = describe_package(full);

    // Cut at the end of the second section: a valid, lower-quality package.
    const fs::path prefix = dir.path() / "prefix.btfpkg";
    write_file(prefix, bytes.substr(0, whole.sections[1].offset + 200));
    const CatalogEntry e = describe_package(prefix);
    EXPECT_EQ(e.sections.size(), 2u);
    EXPECT_EQ(e.bytes, whole.sections[2].offset);

    // Cut inside a section, or with bytes after the last one.
    const fs::path cut = dir.path() / "cut.btfpkg";
    write_file(cut, bytes.substr(0, whole.sections[1].offset + 50));
    EXPECT_EQ(error_of([&] { describe_package(cut); }),
              fmt::format("{}: section 's1' is truncated: 50 of 200 bytes present (from byte {})",
                          cut.string(), whole.sections[1].offset));
    const fs::path longer = dir.path() / "longer.btfpkg";
    write_file(longer, bytes + "xyz");
    EXPECT_EQ(error_of([&] { describe_package(longer); }),
              fmt::format("{}: 3 trailing bytes after the last section (from byte {})",
                          longer.string(), bytes.size()));
}

TEST(Catalog, ListsBsvtfPackagesOfAFolder) {
    TempFolder dir;
    make_package(dir.path() / "stone.bsvtf", {10});
    {
        // A BSVTF package: its extent and sampling are those of its source (bsvtf/file.h).
        Package b;
        b.header = {{"codec", "bsvtf"},
                    {"source",
                     {{"width", 16},
                      {"height", 8},
                      {"views", {{"theta", {0.0}}, {"phi", {0.0}}}},
                      {"lights", {{"theta", {0.0, 0.3}}, {"phi", {0.0, 1.0}}}}}}};
        write_package(dir.path() / "stone.bsvtf", b);
    }
    make_package(dir.path() / "cloth.btfpkg", {10});
    write_file(dir.path() / "notes.txt", "not a package");
    const Catalog catalog = Catalog::build({dir.path()});
    ASSERT_EQ(catalog.size(), 2u);
    EXPECT_EQ(catalog.entries()[0].id, "cloth");
    EXPECT_EQ(catalog.entries()[1].id, "stone");
    EXPECT_EQ(catalog.entries()[1].name, "stone");
    EXPECT_EQ(catalog.entries()[1].to_json(true)["package"], "materials/stone.btfpkg");
    EXPECT_EQ(catalog.entries()[1].codec, "bsvtf");
    EXPECT_EQ(catalog.entries()[1].width, 16);
    EXPECT_EQ(catalog.entries()[1].lights, 2);
}

TEST(Catalog, ReportsBadInputs) {
    TempFolder dir;
    const fs::path missing = dir.path() / "missing.btfpkg";
    EXPECT_EQ(error_of([&] { Catalog::build({missing}); }),
              missing.string() + ": no such file or folder");
    const fs::path text = dir.path() / "text.btfpkg";
    write_file(text, "this is not a package at all");
    EXPECT_EQ(error_of([&] { describe_package(text); }),
              text.string() + ": not a btfkit package (bad magic)");
    const fs::path empty = dir.path() / "empty";
    fs::create_directories(empty);
    write_file(empty / "notes.txt", "no packages here");
    EXPECT_EQ(error_of([&] { Catalog::build({empty}); }),
              empty.string() + ": no *.btfpkg or *.bsvtf packages in this folder");

    // A package without the extent fields (a codec that does not write them).
    Package package;
    package.header = {{"codec", "test"}};
    const fs::path bare = dir.path() / "bare.btfpkg";
    write_package(bare, package);
    EXPECT_NE(error_of([&] { describe_package(bare); }).find(bare.string() + ": bad header:"),
              std::string::npos);
    // A header cut short.
    const fs::path short_header = dir.path() / "short.btfpkg";
    make_package(short_header, {10});
    write_file(short_header, read_file(short_header).substr(0, 40));
    EXPECT_NE(error_of([&] { describe_package(short_header); }).find("truncated in the header"),
              std::string::npos);
}

TEST(Catalog, UniqueIdsAndListJson) {
    TempFolder dir;
    for (const char* folder : {"a", "b", "c"}) {
        fs::create_directories(dir.path() / folder);
        make_package(dir.path() / folder / "fabric.btfpkg", {10});
    }
    make_package(dir.path() / "a" / "My Fabric.btfpkg", {10});
    make_package(dir.path() / "Fabric.BTFPKG", {10});
    const Catalog catalog = Catalog::build({dir.path() / "a", dir.path() / "b", dir.path() / "c",
                                            dir.path() / "a" / "fabric.btfpkg",  // listed already
                                            dir.path() / "Fabric.BTFPKG"});
    std::vector<std::string> ids;
    for (const CatalogEntry& e : catalog.entries()) ids.push_back(e.id);
    // Ids differ without case too, so a bundle works on case-insensitive file systems.
    EXPECT_EQ(
        ids, (std::vector<std::string>{"My_Fabric", "fabric", "fabric-2", "fabric-3", "Fabric-4"}));
    EXPECT_EQ(catalog.entries()[0].name, "My Fabric");
    ASSERT_NE(catalog.find("fabric-2"), nullptr);
    EXPECT_EQ(catalog.find("fabric-2")->path, fs::canonical(dir.path() / "b" / "fabric.btfpkg"));
    EXPECT_EQ(catalog.find("nope"), nullptr);

    const json served = json::parse(dump_json(catalog.to_json(true)));
    EXPECT_EQ(served.at("protocol"), 1);
    EXPECT_EQ(served["materials"][2].at("stream"), "stream/fabric-2");
    EXPECT_EQ(served["materials"][2].at("package"), "materials/fabric-2.btfpkg");
    const json bundled = json::parse(dump_json(catalog.to_json(false)));
    EXPECT_TRUE(bundled["materials"][2].at("stream").is_null());
}

TEST(Catalog, LongIdsKeepTheirSuffixWithinTheLimit) {
    TempFolder dir;
    const std::string name(80, 'x');
    for (const char* folder : {"a", "b"}) {
        fs::create_directories(dir.path() / folder);
        make_package(dir.path() / folder / (name + ".btfpkg"), {10});
    }
    const Catalog catalog = Catalog::build({dir.path() / "a", dir.path() / "b"});
    EXPECT_EQ(catalog.entries()[0].id, std::string(64, 'x'));
    EXPECT_EQ(catalog.entries()[1].id, std::string(62, 'x') + "-2");
}

TEST(Catalog, IndexPageLinksEveryMaterial) {
    TempFolder dir;
    make_package(dir.path() / "a<b>.btfpkg", {10});
    const Catalog catalog = Catalog::build({dir.path() / "a<b>.btfpkg"});
    const std::string page = index_page(catalog, "viewer & co. not built", false);
    EXPECT_NE(page.find("href=\"materials/a_b_.btfpkg\""), std::string::npos);
    EXPECT_NE(page.find("a&lt;b&gt;"), std::string::npos);
    EXPECT_NE(page.find("viewer &amp; co. not built"), std::string::npos);
    EXPECT_EQ(page.find("WebSocket"), std::string::npos);
}

// ---- bundles -----------------------------------------------------------------------------------

TEST(Bundle, WritesTheStaticLayout) {
    TempFolder dir;
    make_package(dir.path() / "one.btfpkg", {100, 70000});
    make_package(dir.path() / "two.btfpkg", {5});
    const fs::path web = dir.path() / "web";
    fs::create_directories(web / "assets");
    write_file(web / "index.html", "<!doctype html><title>viewer</title>");
    write_file(web / "assets" / "viewer.js", "let x = 1;");
    write_file(web / ".cache", "not part of the site");
    fs::create_symlink(web / "assets" / "viewer.js", web / "viewer.js");

    const Catalog catalog = Catalog::build({dir.path() / "one.btfpkg", dir.path() / "two.btfpkg"});
    const fs::path site = dir.path() / "site";
    const BundleResult result = write_bundle(catalog, web, site);
    EXPECT_EQ(result.materials, 2u);
    EXPECT_TRUE(result.viewer);
    EXPECT_EQ(read_file(site / "index.html"), "<!doctype html><title>viewer</title>");
    EXPECT_EQ(read_file(site / "assets" / "viewer.js"), "let x = 1;");
    EXPECT_EQ(read_file(site / "viewer.js"), "let x = 1;");
    EXPECT_FALSE(fs::exists(site / ".cache"));
    EXPECT_EQ(read_file(site / "materials" / "one.btfpkg"), read_file(dir.path() / "one.btfpkg"));
    EXPECT_EQ(read_file(site / "materials" / "two.btfpkg"), read_file(dir.path() / "two.btfpkg"));
    const json list = json::parse(read_file(site / "api" / "materials"));
    EXPECT_EQ(list, json::parse(dump_json(catalog.to_json(false))));
    EXPECT_TRUE(list["materials"][0]["stream"].is_null());
    // Nothing else is left beside the site.
    int entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++entries;
    EXPECT_EQ(entries, 4);  // one, two, web, site

    // A non-empty folder is refused and left as it was; an empty one is filled.
    EXPECT_EQ(error_of([&] { write_bundle(catalog, web, site); }),
              site.string() + ": folder exists and is not empty (bundle writes a new folder)");
    EXPECT_TRUE(fs::exists(site / "materials" / "one.btfpkg"));
    const fs::path empty = dir.path() / "empty";
    fs::create_directories(empty);
    write_bundle(catalog, {}, empty.string() + "/");
    EXPECT_TRUE(fs::exists(empty / "materials" / "two.btfpkg"));
    EXPECT_NE(read_file(empty / "index.html").find("href=\"materials/one.btfpkg\""),
              std::string::npos);
}

TEST(Bundle, RefusesLinksOutOfTheWebRoot) {
    TempFolder dir;
    make_package(dir.path() / "one.btfpkg", {10});
    const fs::path web = dir.path() / "web";
    fs::create_directories(web);
    write_file(web / "index.html", "viewer");
    write_file(dir.path() / "secret.txt", "secret");
    fs::create_symlink(dir.path() / "secret.txt", web / "secret.txt");
    const Catalog catalog = Catalog::build({dir.path() / "one.btfpkg"});
    const fs::path site = dir.path() / "site";
    EXPECT_EQ(error_of([&] { write_bundle(catalog, web, site); }),
              (fs::canonical(web) / "secret.txt").string() +
                  ": symbolic link points outside the web root");
    EXPECT_FALSE(fs::exists(site));
}

}  // namespace
}  // namespace btf::stream
