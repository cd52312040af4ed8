// SPDX-License-Identifier: MIT
// btf decompress PKG -o OUT.h5|DIR: decode a package to a raw BTF (btfkit HDF5 or a UTIA image
// set), every sample evaluated by its codec.

#include <cstdio>

#include "btf/codecs/material_source.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

Command register_decompress(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string input, output;
        RawOutputOptions raw;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "decompress",
        "Decode a btfkit package (or a prefix of one) to btfkit HDF5 (OUT ends in .h5) or a UTIA "
        "image set (OUT without an extension: a new folder)");
    cmd->add_option("package", args->input, "btfkit package (.btfpkg) or BSVTF file (.bsvtf)")
        ->required();
    cmd->add_option("-o,--output", args->output,
                    "output .h5 file or new folder (must not be an existing folder)")
        ->required();
    add_raw_output_options(*cmd, args->raw);

    return {cmd, [args, &global] {
                const OutputKind kind = output_kind(args->output);
                if (kind != OutputKind::kHdf5 && kind != OutputKind::kFolder)
                    fail(
                        "{}: unknown output type '{}': name a .h5 file, or a folder without an "
                        "extension for a UTIA image set",
                        args->output, lower_extension(args->output));
                const auto source = open_package_source(args->input);
                Progress progress = make_progress(global);
                write_raw(*source, args->output, args->raw, progress);
                if (!global.quiet) std::printf("wrote %s\n", args->output.c_str());
            }};
}

}  // namespace btf::cli
