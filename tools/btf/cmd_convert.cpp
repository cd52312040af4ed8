// btf convert IN OUT: any reader → btfkit HDF5 (.h5), UBO2014 DFMF (.btf) or a UTIA image set.

#include <algorithm>
#include <cstdio>

#include "btf/io/h5.h"
#include "btf/io/ubo2014.h"
#include "btf/io/utia.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {
std::string lower_extension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    return ext;
}
}  // namespace

Command register_convert(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string input, output, views, format;
        OpenOptions open;
        bool use_float = false;
        int deflate = 0;
        int components = 16;
        std::string colour = "model11";
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "convert",
        "Convert a BTF: to btfkit HDF5 (OUT ends in .h5), UBO2014 DFMF (OUT ends in "
        ".btf) or a UTIA image set (any other OUT: a new folder)");
    cmd->add_option("input", args->input, "BTF file or folder (any format btfkit reads)")
        ->required();
    cmd->add_option("output", args->output,
                    "output file or folder (must not be an existing folder)")
        ->required();
    cmd->add_option("--format", args->format,
                    "UTIA image format: png (8-bit sRGB) or exr (half float XYZ); default png, "
                    "exr for HDR sources")
        ->check(CLI::IsMember({"png", "exr"}));
    cmd->add_flag("--float", args->use_float, "HDF5: store float32 instead of half floats");
    cmd->add_option("--deflate", args->deflate, "HDF5: deflate level 0-9 (0 = uncompressed)")
        ->check(CLI::Range(0, 9));
    cmd->add_option("--components", args->components,
                    "DFMF: components per colour channel of the exact factorization")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--colour", args->colour, "DFMF colour model: model11 (log Y, U/Y, V/Y) or rgb")
        ->check(CLI::IsMember({"model11", "rgb"}));
    add_open_options(*cmd, args->open, args->views);

    return {cmd, [args, &global] {
                const auto source =
                    open_source(args->input, finish_open_options(args->open, args->views));
                Progress progress = make_progress(global);
                const std::string ext = lower_extension(args->output);
                if (ext == ".h5" || ext == ".hdf5") {
                    h5::WriteOptions options;
                    options.half = !args->use_float;
                    options.deflate = args->deflate;
                    h5::write(*source, args->output, options, progress);
                } else if (ext == ".btf") {
                    ubo2014::FactorizeOptions options;
                    options.components = args->components;
                    options.color_model = args->colour == "rgb" ? ubo2014::kColorModelRgb
                                                                : ubo2014::kColorModelLogYUV;
                    ubo2014::write_dfmf(args->output, *source, options, progress);
                } else {
                    if (!ext.empty())
                        fail(
                            "{}: unknown output type '{}': name a .h5 or .btf file, or a folder "
                            "without an extension for a UTIA image set",
                            args->output, ext);
                    std::string format = args->format;
                    if (format.empty()) format = source->info().hdr ? "exr" : "png";
                    utia::write(*source, args->output, format, progress);
                }
                if (!global.quiet) std::printf("wrote %s\n", args->output.c_str());
            }};
}

}  // namespace btf::cli
