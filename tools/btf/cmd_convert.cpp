// SPDX-License-Identifier: MIT
// btf convert IN OUT: any reader or package → btfkit HDF5 (.h5), UBO2014 DFMF (.btf) or a UTIA
// image set; a UBO2014 .btf → an fmf package (.btfpkg) with its own factors.

#include <cstdio>

#include "btf/codecs/dfmf_export.h"
#include "btf/io/ubo2014.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

// A UBO2014 file's factors re-wrapped as an fmf package (seconds, no factorization).
void convert_ubo2014_to_package(const std::string& input, const std::string& output,
                                const std::string& views, const GlobalOptions& global) {
    if (!ubo2014::probe(input)) {
        if (!std::filesystem::exists(input)) fail("{}: no such file", input);
        fail(
            "{}: btf convert writes a package only from a UBO2014 .btf file, whose factors it "
            "keeps; make one from other data with btf compress",
            input);
    }
    if (!views.empty())
        fail("{}: --views does not apply to a package of the file's own factors", input);
    write_ubo2014_package(input, output, global);
    if (!global.quiet) std::printf("wrote %s\n", output.c_str());
}

}  // namespace

Command register_convert(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string input, output, views;
        OpenOptions open;
        RawOutputOptions raw;
        int components = 16;
        std::string colour = "model11";
        bool half = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "convert",
        "Convert a BTF: to btfkit HDF5 (OUT ends in .h5), UBO2014 DFMF (OUT ends in "
        ".btf) or a UTIA image set (any other OUT: a new folder); a UBO2014 .btf to an fmf "
        "package of its own factors, without refactorizing (OUT ends in .btfpkg)");
    cmd->add_option("input", args->input,
                    "BTF file or folder (any format btfkit reads, or a .btfpkg package)")
        ->required();
    cmd->add_option("output", args->output,
                    "output file or folder (must not be an existing folder)")
        ->required();
    add_raw_output_options(*cmd, args->raw);
    cmd->add_option("--components", args->components,
                    "DFMF: components per colour channel of the streaming fmf factorization")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--colour", args->colour, "DFMF colour model: model11 (log Y, U/Y, V/Y) or rgb")
        ->check(CLI::IsMember({"model11", "rgb"}));
    cmd->add_flag("--half", args->half, "DFMF: store the factors as half floats (float32 default)");
    add_open_options(*cmd, args->open, args->views);

    return {cmd, [args, &global] {
                const OutputKind kind = output_kind(args->output);
                if (kind == OutputKind::kPackage) {
                    convert_ubo2014_to_package(args->input, args->output, args->views, global);
                    return;
                }
                if (kind != OutputKind::kHdf5 && kind != OutputKind::kDfmf &&
                    kind != OutputKind::kFolder)
                    fail(
                        "{}: unknown output type '{}': name a .h5, .btf or .btfpkg file, or a "
                        "folder without an extension for a UTIA image set",
                        args->output, lower_extension(args->output));
                const auto source = open_input(args->input, args->open, args->views);
                Progress progress = make_progress(global);
                if (kind == OutputKind::kDfmf) {
                    DfmfExportOptions options;
                    options.components = args->components;
                    options.color_model = args->colour == "rgb" ? ubo2014::kColorModelRgb
                                                                : ubo2014::kColorModelLogYUV;
                    options.scalar_size = args->half ? 2 : 4;
                    export_dfmf(args->output, *source, options, progress);
                } else {
                    write_raw(*source, args->output, args->raw, progress);
                }
                if (!global.quiet) std::printf("wrote %s\n", args->output.c_str());
            }};
}

}  // namespace btf::cli
