// SPDX-License-Identifier: MIT
// btf image-diff A B: how different two pictures of one scene look (ΔE00, SSIM, PSNR), e.g. a
// screenshot of the web viewer against `btf render` of the same scene. Pictures in display
// formats (PNG, JPEG) are compared as shown; linear ones (EXR, HDR, …) are tone-mapped first,
// exactly as `btf render` writes its PNGs.

#include <cstdio>

#include <nlohmann/json.hpp>

#include "btf/core/image.h"
#include "btf/quality/render_compare.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

struct ImageDiffArgs {
    std::string a, b, output;
    double exposure = 0;
    bool json = false;
};

Image display_values(const std::string& path, double exposure) {
    const Image image = read_image(path);
    return is_float_image_format(path) ? quality::tone_map(image, exposure) : image;
}

void run_image_diff(const ImageDiffArgs& args) {
    if (!args.output.empty()) {
        if (is_float_image_format(args.output))
            fail("{}: the comparison is a picture: give a .png or .jpg output", args.output);
        check_image_output(args.output);
    }
    const Image a = display_values(args.a, args.exposure);
    const Image b = display_values(args.b, args.exposure);
    if (a.width() != b.width() || a.height() != b.height())
        fail("{}: {} × {} pixels, but {} has {} × {}", args.b, b.width(), b.height(), args.a,
             a.width(), a.height());
    const quality::RenderComparison c = quality::compare_displays(a, b);
    if (!args.output.empty()) {
        AtomicOutputSet out;  // a temporary name that keeps the extension, renamed when written
        write_image(out.add(args.output), quality::side_by_side(a, b, c.heat_map));
        out.commit();
    }
    if (args.json) {
        nlohmann::json metrics = quality::metrics_json(c);
        metrics.update(
            {{"a", args.a}, {"b", args.b}, {"width", a.width()}, {"height", a.height()}});
        std::printf("%s\n", metrics.dump(2).c_str());
        return;
    }
    std::printf("%s\n", quality::summary(c).c_str());
    if (!args.output.empty())
        std::printf("%s: A | B | ΔE00 from 0 (dark) to %g (bright)\n", args.output.c_str(),
                    c.heat_max);
}

}  // namespace

Command register_image_diff(CLI::App& app, GlobalOptions& global) {
    auto args = std::make_shared<ImageDiffArgs>();
    CLI::App* cmd = app.add_subcommand(
        "image-diff",
        "Compare two pictures of one scene as a display shows them: ΔE00 (mean, 95th "
        "percentile), SSIM, PSNR. PNG/JPEG are taken as shown; EXR/HDR are tone-mapped like "
        "`btf render`'s PNGs");
    cmd->add_option("a", args->a, "first picture")->required()->check(CLI::ExistingFile);
    cmd->add_option("b", args->b, "second picture, of the same size")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("-o,--output", args->output, "write A | B | ΔE00 heat map (.png)");
    cmd->add_option("--exposure", args->exposure, "exposure in EV for linear pictures");
    cmd->add_flag("--json", args->json, "print the metrics as JSON");
    return {cmd, [args] { run_image_diff(*args); }};
}

}  // namespace btf::cli
