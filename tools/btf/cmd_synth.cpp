// SPDX-License-Identifier: MIT
// btf synth: render a realistic synthetic material to btfkit HDF5.

#include <cstdio>

#include "btf/io/h5.h"
#include "btf/synth/synth.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

Command register_synth(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string preset = "woven_fabric", sampling = "ubo81", output;
        int size = 64;
        uint64_t seed = 1;
        bool list = false, use_float = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "synth",
        "Render a synthetic BTF (height-field mesostructure, shadows, masking, parallax, "
        "microfacet reflectance) to btfkit HDF5");
    cmd->add_option("--preset", args->preset, "material preset (--list shows them)");
    cmd->add_option("--size", args->size, "texels per side")
        ->check(CLI::Range(synth::kMinSize, synth::kMaxSize));
    cmd->add_option("--sampling", args->sampling,
                    "direction set for lights and views: ubo81, dome151 or a direction-set file");
    cmd->add_option("--seed", args->seed, "random seed (same seed, same material)");
    cmd->add_option("-o,--output", args->output, "output .h5 file");
    cmd->add_flag("--list", args->list, "list the presets and exit");
    cmd->add_flag("--float", args->use_float, "store float32 instead of half floats");

    return {cmd, [args, &global] {
                if (args->list) {
                    for (const synth::PresetInfo& preset : synth::presets())
                        std::printf("%-18s %s\n", preset.name.c_str(), preset.description.c_str());
                    return;
                }
                if (args->output.empty()) throw CLI::RequiredError("-o,--output");
                const std::string ext = std::filesystem::path(args->output).extension().string();
                if (ext != ".h5" && ext != ".hdf5")
                    fail("{}: synth writes btfkit HDF5: name the output *.h5", args->output);
                const DirectionSet set = DirectionSet::named(args->sampling);
                const auto source =
                    synth::make(args->preset, args->size, Sampling{set, set}, args->seed);
                Progress progress = make_progress(global);
                h5::WriteOptions options;
                options.half = !args->use_float;
                h5::write(*source, args->output, options, progress);
                if (!global.quiet) std::printf("wrote %s\n", args->output.c_str());
            }};
}

}  // namespace btf::cli
