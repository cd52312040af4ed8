// SPDX-License-Identifier: MIT
// btf bundle PKG... -o site/ [--web DIR]: the viewer and the packages as a static site
// (docs/protocol.md, "Static bundles") for any web server that serves files and byte ranges.

#include <cstdio>
#include <filesystem>

#include "btf/stream/bundle.h"
#include "btf/stream/catalog.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace fs = std::filesystem;

Command register_bundle(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::vector<std::string> inputs;
        std::string output, web;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "bundle",
        "Write the web viewer and compressed materials as a static site (index.html, "
        "api/materials, materials/<id>.btfpkg) for any web server");
    cmd->add_option("inputs", args->inputs,
                    "btfkit packages (*.btfpkg, *.bsvtf), UBO2014 .btf files or folders of "
                    "packages")
        ->required();
    cmd->add_option("-o,--output", args->output, "site folder to create (new or empty)")
        ->required();
    cmd->add_option("--web", args->web,
                    "the web viewer's folder (default: the installed viewer, "
                    "PREFIX/share/btfkit/web beside PREFIX/bin/btf, else the build's own)");

    return {cmd, [args, &global] {
                fs::path web_root;
                if (!args->web.empty()) {
                    std::error_code ec;
                    if (!fs::is_directory(args->web, ec))
                        fail("{}: --web: no such folder", args->web);
                    web_root = args->web;
                } else if (std::error_code ec; fs::is_directory(default_web_dir(), ec)) {
                    web_root = default_web_dir();
                }
                const stream::Catalog catalog =
                    stream::Catalog::build(servable_inputs(args->inputs, global));
                Progress progress = make_progress(global);
                const stream::BundleResult result =
                    stream::write_bundle(catalog, web_root, args->output, progress);
                if (global.quiet) return;
                std::printf("wrote %s: %zu material%s, %s, %s\n", args->output.c_str(),
                            result.materials, result.materials == 1 ? "" : "s",
                            human_bytes(double(result.bytes)).c_str(),
                            result.viewer ? ("viewer from " + web_root.string()).c_str()
                                          : "no viewer build (a plain index page lists the "
                                            "materials)");
            }};
}

}  // namespace btf::cli
