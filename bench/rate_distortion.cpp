// SPDX-License-Identifier: MIT
// Rate–distortion of every compiled-in codec (btf::codecs()) at several sizes, on the real
// measured UBO2003 view (1 view × 81 lights, 256²) and on synthetic materials (default
// woven_fabric and leather, 128² × 81 × 81).
//
// Ratio: the raw BTF as 8-bit RGB (W·H·views·lights·3 bytes) over the package file size
// (encode_package, zstd level 9). Errors over every sample (texel, view, light) through the
// decoded material's eval_sample() against the source: RMSE of linear RGB, PSNR with peak 1.0,
// and the mean CIELab ΔE76 (btf::rgb_to_lab on linear RGB, negatives clamped to 0). Encode time
// is codec.encode() on an in-memory copy of the source.
//
// A last table repeats the configurations of Sotnychenko's thesis, Table 6.1 (§6.1, pp. 37–38;
// pca-views k = 1 and 3, C = 8 and 32 on the Bonn wool sample) on the synthetic knitted_wool
// preset and the real view, with the thesis's own error measures: MAE in CIELab (mean absolute
// difference per L, a, b channel, averaged over the channels), and MAE and RMSE of 8-bit sRGB
// values.
//
//   build/<dir>/rate_distortion [--size 128] [--presets woven_fabric,leather] [--data DIR|-]
//                               [--thesis-preset knitted_wool|-]

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/codec.h"
#include "btf/core/color.h"
#include "btf/io/open.h"
#include "btf/synth/synth.h"

namespace {

using namespace btf;
namespace fs = std::filesystem;

struct Config {
    std::string label;  // shown in the codec column
    std::map<std::string, std::string> params;
};

// The sizes measured per codec. A codec of the registry that is not listed is reported as
// skipped.
std::vector<std::pair<std::string, std::vector<Config>>> configurations() {
    auto list = [](const std::string& label, const std::string& key, const std::vector<int>& values,
                   std::map<std::string, std::string> fixed) {
        std::vector<Config> out;
        for (int v : values) {
            Config c{label, fixed};
            c.params[key] = std::to_string(v);
            out.push_back(std::move(c));
        }
        return out;
    };
    std::vector<Config> fmf = list("fmf rgb", "components", {8, 16, 32}, {{"colour", "rgb"}});
    for (Config& c :
         list("fmf decorrelated", "components", {8, 16, 32}, {{"colour", "decorrelated"}}))
        fmf.push_back(std::move(c));
    std::vector<Config> pca =
        list("pca-views k=1", "components", {2, 4, 8}, {{"views-per-group", "1"}});
    pca.push_back({"pca-views k=3", {{"views-per-group", "3"}, {"components", "8"}}});
    std::vector<Config> lpca;
    for (auto [clusters, components] : {std::pair{4, 4}, {7, 5}, {16, 8}})
        lpca.push_back(
            {"lpca",
             {{"clusters", std::to_string(clusters)}, {"components", std::to_string(components)}}});
    return {{"fmf", fmf}, {"pca-views", pca}, {"lpca", lpca}};
}

std::string params_text(const Config& c) {
    std::string s;
    for (const auto& [key, value] : c.params) {
        if (key == "colour") continue;  // in the label
        if (key == "views-per-group") continue;
        s += (s.empty() ? "" : " ") + key + "=" + value;
    }
    return s;
}

struct Dataset {
    std::string name;
    std::unique_ptr<bench::MemorySource> source;
    std::vector<float> lab;  // per sample (image-major, then texel): L, a, b of the source
};

Dataset load(std::string name, const BtfSource& source) {
    Dataset d;
    d.name = std::move(name);
    d.source = std::make_unique<bench::MemorySource>(source);
    const int64_t texels = source.num_texels();
    const int nl = source.num_lights();
    d.lab.resize(size_t(source.sampling().num_images()) * texels * 3);
    parallel_for(0, source.sampling().num_images(), [&](int64_t i) {
        const float* p = d.source->pixels(int(i / nl), int(i % nl));
        float* out = d.lab.data() + i * texels * 3;
        for (int64_t t = 0; t < texels; ++t) {
            const Lab lab = rgb_to_lab({std::max(p[3 * t], 0.0f), std::max(p[3 * t + 1], 0.0f),
                                        std::max(p[3 * t + 2], 0.0f)});
            out[3 * t] = float(lab.l);
            out[3 * t + 1] = float(lab.a);
            out[3 * t + 2] = float(lab.b);
        }
    });
    return d;
}

struct Errors {
    double squared = 0, delta_e = 0, lab_mae = 0, srgb_abs = 0, srgb_squared = 0;
    int64_t samples = 0;
    double rmse() const { return std::sqrt(squared / (3.0 * samples)); }
    double psnr() const { return -10 * std::log10(squared / (3.0 * samples)); }
};

// Errors of `material` over every sample of the dataset; `srgb` adds the 8-bit sRGB MAE/RMSE.
Errors measure(const Dataset& d, const Material& material, bool srgb) {
    const BtfSource& s = *d.source;
    const int w = s.width(), h = s.height(), nl = s.num_lights();
    const int64_t texels = s.num_texels();
    const int images = s.sampling().num_images();
    std::vector<Errors> per_image(images);
    parallel_for(0, images, [&](int64_t i) {
        const int view = int(i / nl), light = int(i % nl);
        const float* p = d.source->pixels(view, light);
        const float* lab = d.lab.data() + i * texels * 3;
        Errors e;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const int64_t t = int64_t(y) * w + x;
                const Rgb v = material.eval_sample(x, y, view, light);
                const float ref[3] = {p[3 * t], p[3 * t + 1], p[3 * t + 2]};
                const float got[3] = {v.r, v.g, v.b};
                for (int c = 0; c < 3; ++c)
                    e.squared += double(got[c] - ref[c]) * (got[c] - ref[c]);
                const Lab l =
                    rgb_to_lab({std::max(v.r, 0.0f), std::max(v.g, 0.0f), std::max(v.b, 0.0f)});
                const double dl = l.l - lab[3 * t], da = l.a - lab[3 * t + 1],
                             db = l.b - lab[3 * t + 2];
                e.delta_e += std::sqrt(dl * dl + da * da + db * db);
                e.lab_mae += (std::abs(dl) + std::abs(da) + std::abs(db)) / 3;
                if (srgb)
                    for (int c = 0; c < 3; ++c) {
                        const double diff =
                            255.0 * (linear_to_srgb(std::clamp(got[c], 0.0f, 1.0f)) -
                                     linear_to_srgb(std::clamp(ref[c], 0.0f, 1.0f)));
                        e.srgb_abs += std::abs(diff);
                        e.srgb_squared += diff * diff;
                    }
            }
        e.samples = texels;
        per_image[i] = e;
    });
    Errors total;
    for (const Errors& e : per_image) {
        total.squared += e.squared;
        total.delta_e += e.delta_e;
        total.lab_mae += e.lab_mae;
        total.srgb_abs += e.srgb_abs;
        total.srgb_squared += e.srgb_squared;
        total.samples += e.samples;
    }
    return total;
}

struct Outcome {
    double ratio = 0, seconds = 0;
    Errors errors;
};

Outcome run(const Dataset& d, const Codec& codec, const Config& config, bool srgb) {
    const BtfSource& s = *d.source;
    Outcome o;
    bench::Stopwatch clock;
    Package package = codec.encode(s, Params(config.params));
    o.seconds = clock.seconds();
    const std::vector<uint8_t> bytes = encode_package(package);
    o.ratio = double(s.num_texels()) * s.sampling().num_images() * 3 / double(bytes.size());
    const auto material = codec.open(decode_package(bytes, config.label));
    clock = bench::Stopwatch();
    o.errors = measure(d, *material, srgb);
    std::fprintf(stderr, "%s %s %s: encode %.1f s, errors %.1f s\n", d.name.c_str(),
                 config.label.c_str(), params_text(config).c_str(), o.seconds, clock.seconds());
    return o;
}

}  // namespace

int main(int argc, char** argv) {
    int size = 128;
    std::vector<std::string> presets = {"woven_fabric", "leather"};
    std::string thesis_preset = "knitted_wool";
    fs::path data = fs::path(BTF_SHARED_DIR) / "data" / "ubo2003-proposte-view000";
    CLI::App app{"Rate-distortion of every codec (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side of the synthetic presets")
        ->capture_default_str();
    app.add_option("--presets", presets, "synthetic presets")->delimiter(',');
    app.add_option("--data", data, "the real measured view, or - for none")->capture_default_str();
    app.add_option("--thesis-preset", thesis_preset, "preset of the thesis comparison, or -")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        const auto configs = configurations();
        const DirectionSet& ubo = DirectionSet::ubo81();
        std::vector<std::pair<std::string, Outcome>> thesis_rows;

        auto table = [&](const Dataset& d) {
            const BtfSource& s = *d.source;
            std::printf("\n%s: %d² texels × %d views × %d lights (8-bit raw %.1f MB)\n\n",
                        d.name.c_str(), s.width(), s.num_views(), s.num_lights(),
                        double(s.num_texels()) * s.sampling().num_images() * 3 / 1e6);
            std::printf(
                "| codec | params | ratio | RMSE | PSNR | mean ΔE76 | encode time |\n"
                "|---|---|---|---|---|---|---|\n");
            for (const Codec* codec : codecs()) {
                const auto it =
                    std::find_if(configs.begin(), configs.end(),
                                 [&](const auto& entry) { return entry.first == codec->name(); });
                if (it == configs.end()) {
                    std::printf(
                        "| %s | (no sizes listed in bench/rate_distortion.cpp: skipped) "
                        "| | | | | |\n",
                        std::string(codec->name()).c_str());
                    continue;
                }
                for (const Config& config : it->second) {
                    // Groups of 3 views need more than one view.
                    if (s.num_views() == 1 && config.params.count("views-per-group") &&
                        config.params.at("views-per-group") != "1")
                        continue;
                    try {
                        const Outcome o = run(d, *codec, config, false);
                        std::printf("| %s | %s | %.1f:1 | %.4f | %.2f dB | %.2f | %.1f s |\n",
                                    config.label.c_str(), params_text(config).c_str(), o.ratio,
                                    o.errors.rmse(), o.errors.psnr(),
                                    o.errors.delta_e / double(o.errors.samples), o.seconds);
                    } catch (const btf::Error& e) {
                        std::printf("| %s | %s | failed: %s | | | | |\n", config.label.c_str(),
                                    params_text(config).c_str(), e.what());
                    }
                    std::fflush(stdout);
                }
            }
        };
        auto thesis = [&](const Dataset& d) {
            const Codec& codec = find_codec("pca-views");
            for (auto [k, c] : {std::pair{1, 8}, {3, 8}, {3, 32}}) {
                if (d.source->num_views() == 1 && k != 1) continue;
                const Config config{
                    "pca-views",
                    {{"views-per-group", std::to_string(k)}, {"components", std::to_string(c)}}};
                thesis_rows.push_back(
                    {fmt::format("{} | {} | {}", d.name, k, c), run(d, codec, config, true)});
            }
        };

        std::printf("Machine: %u cores.\n", std::thread::hardware_concurrency());
        if (data != "-" && fs::exists(data)) {
            bench::Stopwatch clock;
            const Dataset real = load("real UBO2003 view (PROPOSTE, view 0)", *open_source(data));
            std::fprintf(stderr, "loaded the real view in %.1f s\n", clock.seconds());
            table(real);
            thesis(real);
        } else {
            std::printf("\n(the real view %s is absent: skipped)\n", data.string().c_str());
        }
        for (const std::string& preset : presets) {
            bench::Stopwatch clock;
            const Dataset d =
                load("synthetic " + preset, *synth::make(preset, size, {ubo, ubo}, 1));
            std::fprintf(stderr, "synthesized %s in %.1f s\n", preset.c_str(), clock.seconds());
            table(d);
        }
        if (thesis_preset != "-") {
            const Dataset d = load("synthetic " + thesis_preset,
                                   *synth::make(thesis_preset, size, {ubo, ubo}, 1));
            thesis(d);
        }
        std::printf(
            "\nThesis measures (Sotnychenko 2015, Table 6.1: wool, k = 1, C = 8: MAE CIELab 2.14, "
            "MAE RGB 5.86, RMSE RGB 7.5, 1:23; k = 3, C = 8: 2.19, 6.83, 8.68, 1:70; k = 3, "
            "C = 32: 2.22, 5.92, 7.5, 1:17)\n\n"
            "| material | k | C | MAE CIELab | MAE RGB (8-bit sRGB) | RMSE RGB (8-bit sRGB) | "
            "ratio |\n|---|---|---|---|---|---|---|\n");
        for (const auto& [name, o] : thesis_rows) {
            const double n = double(o.errors.samples);
            std::printf("| %s | %.2f | %.2f | %.2f | 1:%.0f |\n", name.c_str(),
                        o.errors.lab_mae / n, o.errors.srgb_abs / (3 * n),
                        std::sqrt(o.errors.srgb_squared / (3 * n)), o.ratio);
        }
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "rate_distortion: %s\n", e.what());
        return 1;
    }
    return 0;
}
