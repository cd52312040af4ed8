// SPDX-License-Identifier: MIT
#pragma once
/// Static bundles (docs/protocol.md, "Static bundles"): the viewer and the packages laid out so
/// that any web server that serves files and byte ranges serves them, with the same URLs as
/// `btf serve`:
///
///     index.html, the viewer's assets      copied from the web root
///     api/materials                        the material list, "stream": null
///     materials/<id>.btfpkg                the packages

#include <cstdint>
#include <filesystem>

#include "btf/stream/catalog.h"
#include "btf/util/progress.h"

namespace btf::stream {

struct BundleResult {
    size_t materials = 0;
    /// True if the web root held a viewer (an index.html) that was copied; false if the site
    /// got the built-in index page instead.
    bool viewer = false;
    /// Bytes written, all files together.
    uint64_t bytes = 0;
};

/// Writes the site folder `output`, all or nothing: everything goes into a temporary folder
/// beside it that is renamed into place at the end. `web_root` (may be empty) is copied without
/// its hidden files (names starting with '.'); when it has no index.html the site gets the
/// built-in index page listing the materials. Throws btf::Error when `output` exists and is not
/// an empty folder, when a symbolic link in the web root points outside it, or when a package
/// changed since the catalog read it; btf::Cancelled through `progress`.
BundleResult write_bundle(const Catalog& catalog, const std::filesystem::path& web_root,
                          const std::filesystem::path& output,
                          Progress& progress = Progress::none());

}  // namespace btf::stream
