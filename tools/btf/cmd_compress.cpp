// SPDX-License-Identifier: MIT
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
#include "btf/util/collective.h"
#include "btf/util/error.h"
#include "cli.h"
#include "mpi_world.h"

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

void add_encode_options(CLI::App& cmd, EncodeOptions& options) {
    cmd.add_option("--codec", options.codec, "codec name (`btf codecs`)");
    cmd.add_option("--components", options.components,
                   "components to keep (the codec parameter 'components')")
        ->check(CLI::Range(1, 1 << 20));
    cmd.add_option("--quantize", options.quantize,
                   "factor storage (the codec parameter 'quantize')")
        ->check(CLI::IsMember({"f32", "f16", "u8", "coded"}));
    cmd.add_option("--zstd", options.zstd, "zstd level of the package sections (0 = store raw)")
        ->check(CLI::Range(0, 22));
    cmd.add_option("-p,--param", options.params,
                   "codec parameter key=value (repeatable; `btf codecs` lists them)");
    cmd.add_option("--target-size", options.target_size,
                   "largest package file: bytes, or with K, M or G (×1024ⁿ); a factorization "
                   "codec keeps as many components and (with --quantize coded) as high a "
                   "quality as fit, by the least error, from one factorization");
    cmd.add_flag("--no-error", options.no_error,
                 "skip measuring the RMSE (it decodes every sample and reads the input again)");
}

Encoder resolve_encoder(const EncodeOptions& options, size_t inputs) {
    Encoder out;
    out.codec = &find_codec(options.codec);
    out.params = Params::parse(options.params);
    auto shortcut = [&](const char* key, const std::string& value, const char* option) {
        if (out.params.has(key))
            fail("{} and -p {}=… both set '{}': give it once", option, key, key);
        out.params.set(key, value);
    };
    if (options.components > 0)
        shortcut("components", std::to_string(options.components), "--components");
    if (!options.quantize.empty()) shortcut("quantize", options.quantize, "--quantize");
    out.codec->validate(out.params);
    out.codec->check_several(inputs);
    out.factor_codec = dynamic_cast<const factor::FactorCodec*>(out.codec);
    if (!options.target_size.empty()) {
        out.target = parse_size(options.target_size, "--target-size");
        if (!out.factor_codec)
            fail(
                "--target-size: codec {} chooses no size (the factorization codecs do: fmf, "
                "pca-views, lpca, perceptual)",
                out.codec->name());
        if (inputs != 1) fail("--target-size takes one input, not {}", inputs);
    }
    out.write.zstd_level = options.zstd;
    return out;
}

Package encode_one(const Encoder& encoder, const BtfSource& source, Progress& progress,
                   factor::FactorCodec::SizeChoice* choice) {
    if (encoder.target > 0)
        return encoder.factor_codec->encode_to_size(source, encoder.params, encoder.target,
                                                    encoder.write, progress, choice);
    return encoder.codec->encode(source, encoder.params, progress);
}

Command register_compress(CLI::App& app, GlobalOptions& global) {
    auto args = std::make_shared<CompressArgs>();
    CLI::App* cmd = app.add_subcommand(
        "compress",
        "Compress a BTF into a btfkit package (.btfpkg) with a codec (`btf codecs` lists them), "
        "then report size, ratio and the RMSE over every sample; started by mpirun, across the "
        "ranks (docs/distributed.md)");
    cmd->add_option("input", args->inputs,
                    "BTF file or folder (any format btfkit reads, or a package to re-encode); "
                    "with --codec mlvq several, which then share code-books")
        ->required();
    cmd->add_option("-o,--output", args->output, "output package (*.btfpkg)")->required();
    add_encode_options(*cmd, args->encode);
    add_open_options(*cmd, args->open, args->views);

    return {
        cmd, [args, &global] {
            // Across MPI ranks (docs/distributed.md) every rank runs this with the same arguments;
            // what may fail on one rank only runs through together(), so that every rank reports
            // that rank's failure.
            Collective* world = mpi_world();
            Encoder encoder;
            std::vector<std::unique_ptr<BtfSource>> sources;
            together(world, [&] {
                // Everything that can be checked without the input is checked first: opening
                // and encoding a large BTF takes long.
                if (output_kind(args->output) != OutputKind::kPackage)
                    fail("{}: compress writes a btfkit package: name the output *.btfpkg",
                         args->output);
                encoder = resolve_encoder(args->encode, args->inputs.size());
                if (world && !encoder.factor_codec)
                    fail(
                        "codec {} runs in one process: across MPI ranks compress runs the "
                        "factorization codecs (fmf, pca-views, lpca, perceptual); compress-many "
                        "runs any codec, one material per rank",
                        encoder.codec->name());
                for (const std::string& input : args->inputs)
                    sources.push_back(open_input(input, args->open, args->views));
            });
            const ScopedCollective ranks(world);
            Progress progress = make_progress(global);
            const auto start = std::chrono::steady_clock::now();
            Package package;
            factor::FactorCodec::SizeChoice choice;
            if (sources.size() == 1) {
                package = encode_one(encoder, *sources[0], progress, &choice);
            } else {  // the codec's shared package or its refusal
                std::vector<const BtfSource*> list;
                for (const auto& s : sources) list.push_back(s.get());
                package =
                    encoder.codec->encode_several(list, args->inputs, encoder.params, progress);
            }
            // Rank 0 writes (atomically: a failure leaves no file), and every rank learns how
            // that went.
            together(world, [&] {
                if (!world || world->rank() == 0)
                    write_package(args->output, package, encoder.write, progress);
            });
            const double seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

            std::vector<std::optional<double>> rmse(sources.size());
            if (!args->encode.no_error) {
                if (sources.size() == 1) {
                    rmse[0] = sample_rmse(*sources[0], *open_material(package), progress);
                } else {
                    const auto materials = encoder.codec->open_all(package);
                    for (size_t k = 0; k < sources.size(); ++k)
                        rmse[k] = sample_rmse(*sources[k], *materials[k], progress);
                }
            }
            // Bytes each rank sent, for the record (docs/benchmarks.md, "Distributed").
            std::vector<std::string> sent;
            if (world) sent = world->gather(std::to_string(world->bytes_sent()));
            if (world && world->rank() != 0) return;
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
            if (world) line += fmt::format(" on {} MPI ranks", world->size());
            std::printf("%s\n", line.c_str());
            if (encoder.target > 0)
                std::printf(
                    "  target %s: %d of %d components%s, %.1f %% of the target, mean ΔE00 %.3f on "
                    "the sample it was chosen on\n",
                    human_bytes(double(encoder.target)).c_str(), choice.components,
                    choice.factorized,
                    choice.quality >= 0 ? fmt::format(" at quality {:g}", choice.quality).c_str()
                                        : "",
                    100.0 * double(choice.bytes) / double(encoder.target), choice.de2000);
            if (sources.size() > 1)
                for (size_t k = 0; k < sources.size(); ++k)
                    if (rmse[k])
                        std::printf("  %s: RMSE %.3g\n", args->inputs[k].c_str(), *rmse[k]);
            if (world) {
                std::string list;
                for (size_t r = 0; r < sent.size(); ++r)
                    list += fmt::format("{}{} B ({})", r ? ", " : "", sent[r],
                                        human_bytes(std::stod(sent[r])));
                std::printf("  sent by each rank: %s\n", list.c_str());
            }
        }};
}

}  // namespace btf::cli
