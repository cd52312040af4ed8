// SPDX-License-Identifier: MIT
#pragma once
// Shared pieces of the `btf` command: global options, the progress bar, argument parsing.

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/core/direction.h"
#include "btf/core/material.h"
#include "btf/io/open.h"
#include "btf/io/package.h"
#include "btf/util/progress.h"

namespace btf::cli {

/// The git commit `btf` was built from, "" outside a checkout (generated: cmake/git_commit.cmake).
const char* build_commit();
/// What `btf --version` prints and reports name as their writer: "btfkit 0.2.0 (git 1a2b3c4d5e6f)",
/// or "btfkit 0.2.0" when built outside a git checkout.
std::string version_line();

struct GlobalOptions {
    int threads = 0;           // 0 = all cores
    bool quiet = false;        // no progress output
    std::string command_line;  // as typed (shell-quoted where needed), for reports
};

/// The web viewer `btf serve` and `btf bundle` use without --web: the installed one beside this
/// command (PREFIX/share/btfkit/web for PREFIX/bin/btf) when it exists, else this build's output.
std::filesystem::path default_web_dir();

/// A Progress that draws a bar on a terminal (stderr) and prints plain lines otherwise.
Progress make_progress(const GlobalOptions& options);

/// "θ,φ" in degrees → Direction; throws btf::Error naming the option on bad input.
Direction parse_direction(const std::string& text, const std::string& option);
/// "x,y" → two integers.
std::pair<int, int> parse_pair(const std::string& text, const std::string& option);
/// "1,5,7" → indices.
std::vector<int> parse_indices(const std::string& text, const std::string& option);
/// "u,v" → texture coordinates (any finite numbers: they wrap).
Uv parse_uv(const std::string& text, const std::string& option);

/// 1536 → "1.5 KiB".
std::string human_bytes(double bytes);
/// 412.3 → "412:1", 3.14 → "3.1:1".
std::string format_ratio(double ratio);

/// Adds --views and --raw to a subcommand and returns the OpenOptions they fill.
void add_open_options(CLI::App& command, OpenOptions& options, std::string& views_text);
OpenOptions finish_open_options(OpenOptions options, const std::string& views_text);

/// Opens any BTF a reader knows, or a btfkit package (decoded through its codec: a
/// MaterialSource). --views and --raw do not apply to packages and are refused for them.
std::unique_ptr<BtfSource> open_input(const std::string& path, const OpenOptions& options,
                                      const std::string& views_text);

/// A compressed material of any kind btfkit evaluates: a btfkit package, a BSVTF file or a UBO2014
/// .btf file (btf::open_material). Throws btf::Error naming the file when it is missing or none
/// of these.
std::unique_ptr<Material> open_material_file(const std::string& path);

/// What an output name asks for, by its extension.
enum class OutputKind {
    kHdf5,     ///< .h5 / .hdf5
    kDfmf,     ///< .btf
    kPackage,  ///< .btfpkg
    kFolder,   ///< no extension: a UTIA image set folder
    kOther,
};
OutputKind output_kind(const std::string& path);
/// Lower-case extension with its dot ("" for none).
std::string lower_extension(const std::string& path);

/// Options of raw outputs (btfkit HDF5 and UTIA image sets), shared by convert and decompress.
struct RawOutputOptions {
    std::string format;  // UTIA: png or exr; empty = exr for HDR sources, png otherwise
    bool use_float = false;
    int deflate = 0;
};
/// Adds --format, --float and --deflate.
void add_raw_output_options(CLI::App& command, RawOutputOptions& options);
/// write_source() with the command line's options: btfkit HDF5 for a .h5 output, else a new UTIA
/// image set folder (callers check the output's kind before reading their input).
void write_raw(const BtfSource& source, const std::string& output, const RawOutputOptions& options,
               Progress& progress);

/// The BSVTF tile options of `btf bsvtf` and `btf bsvtf-sim`: --tile, --pad, --tile-error and
/// --lossless.
struct TileOptions {
    int tile = 64, pad = 4;
    double tile_error = 0.01;
    bool lossless = false;
    /// The tile codec's relative error: 0 for --lossless.
    double relative_error() const { return lossless ? 0.0 : tile_error; }
};
void add_tile_options(CLI::App& command, TileOptions& options);

/// What compress and compress-many encode with: --codec, -p key=value, the shortcuts
/// --components and --quantize, --target-size, --zstd and --no-error.
struct EncodeOptions {
    std::string codec = "fmf", quantize, target_size;
    int components = 0;  // 0: not given
    int zstd = PackageWriteOptions{}.zstd_level;
    std::vector<std::string> params;
    bool no_error = false;
};
void add_encode_options(CLI::App& command, EncodeOptions& options);
/// The arguments of compress and compress-many.
struct CompressArgs {
    std::vector<std::string> inputs;
    std::string output, views;
    OpenOptions open;
    EncodeOptions encode;
};
/// The options checked and resolved for `inputs` inputs (throws btf::Error naming the option).
struct Encoder {
    const Codec* codec = nullptr;
    const factor::FactorCodec* factor_codec = nullptr;  ///< null for codecs that are not
    Params params;
    uint64_t target = 0;  ///< --target-size in bytes (0: none)
    PackageWriteOptions write;
};
Encoder resolve_encoder(const EncodeOptions& options, size_t inputs);
/// Encodes one source with `encoder` (to its target size when it has one; `choice` is what that
/// chose).
Package encode_one(const Encoder& encoder, const BtfSource& source, Progress& progress,
                   factor::FactorCodec::SizeChoice* choice = nullptr);

/// A subcommand: its CLI11 parser and what to run once arguments are parsed.
struct Command {
    CLI::App* parser = nullptr;
    std::function<void()> run;
};

// One function per subcommand file: declares the options, returns the command.
/// $BTF_CACHE_DIR, else $XDG_CACHE_HOME/btfkit (only an absolute path counts, as the XDG base
/// directory rule says), else ~/.cache/btfkit.
std::filesystem::path cache_folder();
/// The built-in demo material (`btf serve` without packages, `btf render --material demo`):
/// woven_fabric, 128² texels, ubo81 sampling, fmf with 32 components in half floats, made once
/// (about 15 s on two cores) into cache_folder()/demo and reused; a damaged or different file is
/// made again.
std::filesystem::path demo_package(const GlobalOptions& global);
/// Writes the fmf package of the UBO2014 file `input`'s own factors to `output` (dfmf_export.h,
/// package_of): `btf convert X.btf X.btfpkg`, and what serve and bundle make of a .btf input.
void write_ubo2014_package(const std::string& input, const std::filesystem::path& output,
                           const GlobalOptions& global);
/// The inputs of `btf serve` and `btf bundle`, with each UBO2014 .btf file replaced by the fmf
/// package of its own factors (as `btf convert X.btf X.btfpkg` writes it), made once per version
/// of the file (path, size, modification time) into the cache folder and reused after.
std::vector<std::filesystem::path> servable_inputs(const std::vector<std::string>& inputs,
                                                   const GlobalOptions& global);

Command register_info(CLI::App& app, GlobalOptions& global);
Command register_convert(CLI::App& app, GlobalOptions& global);
Command register_synth(CLI::App& app, GlobalOptions& global);
Command register_slice(CLI::App& app, GlobalOptions& global);
Command register_compress_many(CLI::App& app, GlobalOptions& global);
Command register_formats(CLI::App& app, GlobalOptions& global);
Command register_codecs(CLI::App& app, GlobalOptions& global);
Command register_compress(CLI::App& app, GlobalOptions& global);
Command register_decompress(CLI::App& app, GlobalOptions& global);
Command register_eval(CLI::App& app, GlobalOptions& global);
Command register_bench(CLI::App& app, GlobalOptions& global);
Command register_quality(CLI::App& app, GlobalOptions& global);
Command register_report(CLI::App& app, GlobalOptions& global);
Command register_render(CLI::App& app, GlobalOptions& global);
Command register_serve(CLI::App& app, GlobalOptions& global);
Command register_bundle(CLI::App& app, GlobalOptions& global);
Command register_image_diff(CLI::App& app, GlobalOptions& global);
Command register_bsvtf(CLI::App& app, GlobalOptions& global);
Command register_bsvtf_sim(CLI::App& app, GlobalOptions& global);
/// Registered last: btf(1) describes the commands registered before it.
Command register_manpage(CLI::App& app, GlobalOptions& global);

}  // namespace btf::cli
