// SPDX-License-Identifier: MIT
// btf bsvtf PKG -o OUT.bsvtf: the BSVTF preprocessing of an fmf package (src/btf/bsvtf): the
// eigen-textures cut into a mip pyramid of padded tiles with their weights (equation 8), each
// tile compressed against its parent (DCT, quantization, deflate), the Eigen-ABRDFs as packets.

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "btf/bsvtf/file.h"
#include "btf/bsvtf/pyramid.h"
#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/io/package.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

void add_tile_options(CLI::App& command, TileOptions& options) {
    command.add_option("--tile", options.tile, "tile size T in texels")->check(CLI::Range(8, 1024));
    command.add_option("--pad", options.pad, "padding texels on each side of a tile")
        ->check(CLI::Range(2, 64));
    command
        .add_option("--tile-error", options.tile_error,
                    "RMS error the tile compression may add to the eigen-textures, relative to "
                    "their RMS")
        ->check(CLI::Range(1e-6, 1.0));
    command.add_flag("--lossless", options.lossless,
                     "send the tiles' half floats exactly (deflate only)");
}

Command register_bsvtf(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string input, output;
        TileOptions tiles;
        int deflate = 9;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "bsvtf",
        "Preprocess an fmf package for level-of-detail streaming and rendering (BSVTF): "
        "eigen-texture tiles of a mip pyramid with their priorities, compressed for "
        "transmission");
    cmd->add_option("package", args->input, "an fmf package (*.btfpkg)")->required();
    cmd->add_option("-o,--output", args->output, "the BSVTF file to write (*.bsvtf)")->required();
    add_tile_options(*cmd, args->tiles);
    cmd->add_option("--deflate", args->deflate, "deflate level of the tiles")
        ->check(CLI::Range(1, 12));

    return {cmd, [args, &global] {
                const auto start = std::chrono::steady_clock::now();
                Package fmf = read_package(args->input);
                if (fmf.codec() != "fmf")
                    fail(
                        "{}: a '{}' package: btf bsvtf needs an fmf package (btf compress "
                        "--codec fmf)",
                        args->input, fmf.codec());
                { const AtomicOutput probe(args->output); }
                const factor::Model model = factor::from_package(fmf);
                Progress progress = make_progress(global);
                bsvtf::Pyramid pyramid;
                try {
                    pyramid =
                        bsvtf::Pyramid::build(model, {args->tiles.tile, args->tiles.pad}, progress);
                } catch (const Cancelled&) {
                    throw;
                } catch (const Error& e) {
                    fail("{}: {}", args->input, e.what());
                }
                const double relative = args->tiles.relative_error();
                const float step = bsvtf::step_for(pyramid, relative);
                const bsvtf::EncodedPyramid encoded =
                    bsvtf::encode_pyramid(pyramid, step, args->deflate, progress);
                Package out = bsvtf::make_bsvtf(fmf, model, pyramid, encoded, relative);
                write_package(args->output, out, {.zstd_level = 3}, progress);
                const double seconds =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                std::printf(
                    "%s: %d × %d texels, %zu groups of 4 components, %d levels of %d × %d tiles "
                    "(+%d padding): %zu tiles\n",
                    args->output.c_str(), pyramid.width(), pyramid.height(),
                    pyramid.groups().size(), pyramid.levels(), args->tiles.tile, args->tiles.tile,
                    args->tiles.pad, pyramid.tile_count());
                std::printf(
                    "tiles: %s in half floats → %s compressed (%s), %s\n",
                    human_bytes(double(encoded.raw_bytes)).c_str(),
                    human_bytes(double(encoded.encoded_bytes)).c_str(),
                    format_ratio(double(encoded.raw_bytes) / double(encoded.encoded_bytes)).c_str(),
                    args->tiles.lossless
                        ? "lossless"
                        : fmt::format("adding a relative RMS error of {:.4f} to the "
                                      "eigen-textures (at most {})",
                                      encoded.relative_rms_error, relative)
                              .c_str());
                std::printf("file: %s (the fmf package: %s), %.1f s\n",
                            human_bytes(double(out.file_bytes)).c_str(),
                            human_bytes(double(fmf.file_bytes)).c_str(), seconds);
            }};
}

}  // namespace btf::cli
