// btf compress IN -o OUT.btfpkg --codec NAME [-p key=value ...]: encode a BTF into a package and
// say what it cost (size, ratio) and what it lost (RMSE over every sample). With --codec mlvq,
// several inputs share one set of code-books in one package.

#include <chrono>
#include <cstdio>
#include <optional>

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/codecs/material_source.h"
#include "btf/io/package.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

// "123", "400K", "1.5M", "2G" (×1024ⁿ) as bytes.
uint64_t parse_size(const std::string& text, const char* option) {
    size_t used = 0;
    double value = 0;
    try {
        value = std::stod(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    const std::string unit = text.substr(used);
    double scale = 0;
    if (unit.empty())
        scale = 1;
    else if (unit == "K" || unit == "k")
        scale = 1024.0;
    else if (unit == "M")
        scale = 1024.0 * 1024;
    else if (unit == "G")
        scale = 1024.0 * 1024 * 1024;
    if (used == 0 || scale == 0 || !(value > 0) || value * scale > 1e18)
        fail("{} {}: expected a size in bytes, or with K, M or G", option, text);
    return uint64_t(value * scale);
}

}  // namespace

Command register_compress(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::vector<std::string> inputs;
        std::string output, views, codec = "fmf", quantize;
        OpenOptions open;
        int components = 0;
        int zstd = PackageWriteOptions{}.zstd_level;
        std::vector<std::string> params;
        bool no_error = false;
        std::string target_size;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "compress",
        "Compress a BTF into a btfkit package (.btfpkg) with a codec (`btf codecs` lists them), "
        "then report size, ratio and the RMSE over every sample");
    cmd->add_option("input", args->inputs,
                    "BTF file or folder (any format btfkit reads, or a package to re-encode); "
                    "with --codec mlvq several, which then share code-books")
        ->required();
    cmd->add_option("-o,--output", args->output, "output package (*.btfpkg)")->required();
    cmd->add_option("--codec", args->codec, "codec name (`btf codecs`)");
    auto* components = cmd->add_option("--components", args->components,
                                       "components to keep (the codec parameter 'components')")
                           ->check(CLI::Range(1, 1 << 20));
    auto* quantize = cmd->add_option("--quantize", args->quantize,
                                     "factor storage (the codec parameter 'quantize')")
                         ->check(CLI::IsMember({"f32", "f16", "u8", "coded"}));
    cmd->add_option("--zstd", args->zstd, "zstd level of the package sections (0 = store raw)")
        ->check(CLI::Range(0, 22));
    cmd->add_option("-p,--param", args->params,
                    "codec parameter key=value (repeatable; `btf codecs` lists them)");
    cmd->add_option("--target-size", args->target_size,
                    "largest package file: bytes, or with K, M or G (×1024ⁿ); a factorization "
                    "codec keeps as many components and (with --quantize coded) as high a "
                    "quality as fit, by the least error, from one factorization");
    cmd->add_flag("--no-error", args->no_error,
                  "skip measuring the RMSE (it decodes every sample and reads the input again)");
    add_open_options(*cmd, args->open, args->views);

    return {
        cmd, [args, &global, components, quantize] {
            // Everything that can be checked without the input is checked first: opening and
            // encoding a large BTF takes long.
            if (output_kind(args->output) != OutputKind::kPackage)
                fail("{}: compress writes a btfkit package: name the output *.btfpkg",
                     args->output);
            const Codec& codec = find_codec(args->codec);
            Params params = Params::parse(args->params);
            auto shortcut = [&](const char* key, const std::string& value, const char* option) {
                if (params.has(key))
                    fail("{} and -p {}=… both set '{}': give it once", option, key, key);
                params.set(key, value);
            };
            if (components->count())
                shortcut("components", std::to_string(args->components), "--components");
            if (quantize->count()) shortcut("quantize", args->quantize, "--quantize");
            codec.validate(params);
            codec.check_several(args->inputs.size());
            const auto* factor_codec = dynamic_cast<const factor::FactorCodec*>(&codec);
            uint64_t target = 0;
            if (!args->target_size.empty()) {
                target = parse_size(args->target_size, "--target-size");
                if (!factor_codec)
                    fail(
                        "--target-size: codec {} chooses no size (the factorization codecs "
                        "do: fmf, pca-views, lpca, perceptual)",
                        codec.name());
                if (args->inputs.size() != 1)
                    fail("--target-size takes one input, not {}", args->inputs.size());
            }
            std::vector<std::unique_ptr<BtfSource>> sources;
            for (const std::string& input : args->inputs)
                sources.push_back(open_input(input, args->open, args->views));
            Progress progress = make_progress(global);
            const auto start = std::chrono::steady_clock::now();
            Package package;
            PackageWriteOptions write_options;
            write_options.zstd_level = args->zstd;
            factor::FactorCodec::SizeChoice choice;
            if (target > 0) {
                package = factor_codec->encode_to_size(*sources[0], params, target, write_options,
                                                       progress, &choice);
            } else {
                std::vector<const BtfSource*> list;
                for (const auto& s : sources) list.push_back(s.get());
                // One input: encode(); several: the codec's shared package or its refusal.
                package = codec.encode_several(list, args->inputs, params, progress);
            }
            write_package(args->output, package, write_options, progress);
            const double seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

            std::vector<std::optional<double>> rmse(sources.size());
            if (!args->no_error) {
                if (sources.size() == 1) {
                    rmse[0] = sample_rmse(*sources[0], *open_material(package), progress);
                } else {
                    const auto materials = codec.open_all(package);
                    for (size_t k = 0; k < sources.size(); ++k)
                        rmse[k] = sample_rmse(*sources[k], *materials[k], progress);
                }
            }
            double raw_8bit = 0;
            for (const auto& source : sources)
                raw_8bit +=
                    double(source->num_texels()) * double(source->sampling().num_images()) * 3.0;
            const double bytes = double(package.file_bytes);
            std::string line = fmt::format("{}: {}, ratio {} (vs 8-bit RGB raw)", args->output,
                                           human_bytes(bytes), format_ratio(raw_8bit / bytes));
            if (sources.size() == 1 && rmse[0]) line += fmt::format(", RMSE {:.3g}", *rmse[0]);
            if (sources.size() > 1) line += fmt::format(", {} materials", sources.size());
            line +=
                ", encoded in " +
                (seconds < 1 ? fmt::format("{:.2f}", seconds) : fmt::format("{:.1f}", seconds)) +
                " s";
            std::printf("%s\n", line.c_str());
            if (target > 0)
                std::printf(
                    "  target %s: %d of %d components%s, %.1f %% of the target, mean ΔE00 %.3f on "
                    "the sample it was chosen on\n",
                    human_bytes(double(target)).c_str(), choice.components, choice.factorized,
                    choice.quality >= 0 ? fmt::format(" at quality {:g}", choice.quality).c_str()
                                        : "",
                    100.0 * double(choice.bytes) / double(target), choice.de2000);
            if (sources.size() > 1)
                for (size_t k = 0; k < sources.size(); ++k)
                    if (rmse[k])
                        std::printf("  %s: RMSE %.3g\n", args->inputs[k].c_str(), *rmse[k]);
        }};
}

}  // namespace btf::cli
