// SPDX-License-Identifier: MIT
#include "btf/stream/bundle.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

#include "btf/stream/request.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"

namespace btf::stream {

namespace fs = std::filesystem;

namespace {

struct CopyItem {
    fs::path from;      // file to read
    fs::path relative;  // where it goes in the site
    uint64_t size = 0;
};

bool hidden(const fs::path& name) {
    return name.string().starts_with(".");
}

// The web root's files (not its hidden ones), checked before anything is written: a symbolic
// link may point to another place inside the root, never outside it (the server refuses those
// too, so the bundle shows what `btf serve` shows).
std::vector<CopyItem> list_web_files(const fs::path& web_root, std::vector<fs::path>& folders) {
    std::vector<CopyItem> items;
    std::error_code ec;
    const fs::path root = fs::canonical(web_root, ec);
    if (ec) fail("{}: cannot resolve the web root: {}", web_root.string(), ec.message());
    fs::recursive_directory_iterator it(root, fs::directory_options::follow_directory_symlink, ec);
    if (ec) fail("{}: cannot list the web root: {}", web_root.string(), ec.message());
    for (; it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (ec) break;
        const fs::path& path = it->path();
        const fs::path relative = path.lexically_relative(root);
        if (hidden(path.filename())) {
            if (it->is_directory(ec)) it.disable_recursion_pending();
            continue;
        }
        if (it->is_symlink(ec)) {
            const fs::path target = fs::canonical(path, ec);
            if (ec || !inside(target, root))
                fail("{}: symbolic link points outside the web root", path.string());
        }
        if (it->is_directory(ec)) {
            folders.push_back(relative);
        } else if (it->is_regular_file(ec)) {
            items.push_back({path, relative, fs::file_size(path, ec)});
            if (ec) fail("{}: cannot read the file size: {}", path.string(), ec.message());
        }
    }
    if (ec) fail("{}: cannot list the web root: {}", web_root.string(), ec.message());
    return items;
}

void copy_file(const fs::path& from, const fs::path& to, uint64_t expected, Progress& progress) {
    std::ifstream in(from, std::ios::binary);
    if (!in) fail("{}: cannot open for reading: {}", from.string(), std::strerror(errno));
    std::ofstream out(to, std::ios::binary | std::ios::trunc);
    if (!out) fail("{}: cannot open for writing: {}", to.string(), std::strerror(errno));
    std::vector<char> buffer(size_t(1) << 20);
    uint64_t copied = 0;
    while (in) {
        in.read(buffer.data(), std::streamsize(buffer.size()));
        const std::streamsize n = in.gcount();
        if (n <= 0) break;
        out.write(buffer.data(), n);
        if (!out) fail("{}: write error (disk full?)", to.string());
        copied += uint64_t(n);
        progress.advance(uint64_t(n));
    }
    if (in.bad()) fail("{}: read error after {} bytes", from.string(), copied);
    out.close();
    if (!out) fail("{}: write error when closing (disk full?)", to.string());
    if (copied != expected)
        fail("{}: {} bytes read but the file had {} when listed (changed while bundling?)",
             from.string(), copied, expected);
}

void write_text(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(text.data(), std::streamsize(text.size()));
    out.close();
    if (!out) fail("{}: write error (disk full?)", path.string());
}

BundleResult write_site(const Catalog& catalog, const fs::path& web_root, const fs::path& output,
                        Progress& progress) {
    BundleResult result;
    result.materials = catalog.size();
    std::vector<fs::path> folders;
    std::vector<CopyItem> files;
    std::error_code ec;
    if (!web_root.empty()) {
        if (!fs::is_directory(web_root, ec))
            fail("{}: web root is not a folder", web_root.string());
        files = list_web_files(web_root, folders);
        result.viewer = fs::is_regular_file(web_root / "index.html", ec);
    }
    uint64_t total = 0;
    for (const CopyItem& f : files) total += f.size;
    for (const CatalogEntry& e : catalog.entries()) total += e.bytes;

    AtomicOutput site(output, true);
    const fs::path& dir = site.temp_path();
    progress.begin("writing bundle", total);
    for (const fs::path& folder : folders) {
        fs::create_directories(dir / folder, ec);
        if (ec) fail("{}: cannot create folder: {}", (dir / folder).string(), ec.message());
    }
    for (const CopyItem& f : files) {
        copy_file(f.from, dir / f.relative, f.size, progress);
        result.bytes += f.size;
    }
    if (!result.viewer) {
        const std::string page = index_page(
            catalog,
            web_root.empty()
                ? "This site was bundled without the web viewer: this page lists the materials."
                : "The web viewer was not built when this site was bundled (" + web_root.string() +
                      " had no index.html): this page lists the materials.",
            false);
        write_text(dir / "index.html", page);
        result.bytes += page.size();
    }
    for (const char* folder : {"api", "materials"}) {
        fs::create_directories(dir / folder, ec);
        if (ec) fail("{}: cannot create folder: {}", (dir / folder).string(), ec.message());
    }
    const std::string list = dump_json(catalog.to_json(false), 2);
    write_text(dir / "api" / "materials", list);
    result.bytes += list.size();
    for (const CatalogEntry& e : catalog.entries()) {
        // The list describes the file as it was when its header was read.
        std::error_code time_ec;
        if (fs::last_write_time(e.path, time_ec) != e.modified || time_ec)
            fail("{}: the package changed after it was listed", e.path.string());
        copy_file(e.path, dir / "materials" / (e.id + ".btfpkg"), e.bytes, progress);
        result.bytes += e.bytes;
    }
    site.commit();
    progress.finish();
    return result;
}

}  // namespace

BundleResult write_bundle(const Catalog& catalog, const fs::path& web_root, const fs::path& output,
                          Progress& progress) {
    // "site/" names the folder "site".
    fs::path out = output;
    while (!out.empty() && !out.has_filename() && out.has_parent_path() && out != out.root_path())
        out = out.parent_path();
    std::error_code ec;
    bool was_empty_folder = false;
    if (fs::exists(out, ec)) {
        if (!fs::is_directory(out, ec))
            fail("{}: exists and is not a folder (bundle writes a new folder)", output.string());
        if (!fs::is_empty(out, ec))
            fail("{}: folder exists and is not empty (bundle writes a new folder)",
                 output.string());
        // An empty folder is replaced by the finished site in one rename.
        if (!fs::remove(out, ec))
            fail("{}: cannot replace the empty folder: {}", output.string(), ec.message());
        was_empty_folder = true;
    }
    try {
        return write_site(catalog, web_root, out, progress);
    } catch (...) {
        if (was_empty_folder) fs::create_directory(out, ec);
        throw;
    }
}

}  // namespace btf::stream
