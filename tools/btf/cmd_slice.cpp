// btf slice FILE --light θ,φ --view θ,φ -o img.png   |   btf slice FILE --texel x,y -o abrdf.png

#include <cstdio>

#include "btf/io/slice.h"
#include "cli.h"

namespace btf::cli {

Command register_slice(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string path, output, light, view, texel, views;
        OpenOptions open;
        int scale = 4;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd =
        app.add_subcommand("slice",
                           "Write a picture of a BTF: the image at any light and view direction "
                           "(interpolated), or one texel's apparent BRDF");
    cmd->add_option("file", args->path, "BTF file or folder")->required();
    cmd->add_option("-o,--output", args->output, "output image (.png, .jpg: sRGB; .exr: linear)")
        ->required();
    auto* light = cmd->add_option("--light", args->light, "light direction 'theta,phi' in degrees");
    auto* view = cmd->add_option("--view", args->view, "view direction 'theta,phi' in degrees");
    auto* texel = cmd->add_option("--texel", args->texel,
                                  "texel 'x,y': write its ABRDF (rows = views, columns = lights)");
    cmd->add_option("--scale", args->scale, "pixels per ABRDF cell")->check(CLI::Range(1, 64));
    light->needs(view);
    view->needs(light);
    texel->excludes(light)->excludes(view);
    add_open_options(*cmd, args->open, args->views);

    return {cmd, [args, &global] {
                const auto source =
                    open_source(args->path, finish_open_options(args->open, args->views));
                Image image;
                if (!args->texel.empty()) {
                    const auto [x, y] = parse_pair(args->texel, "--texel");
                    Progress progress = make_progress(global);
                    image = abrdf_image(*source, x, y, args->scale, progress);
                } else if (!args->light.empty()) {
                    const Direction wi = parse_direction(args->light, "--light");
                    const Direction wo = parse_direction(args->view, "--view");
                    image = slice_image(*source, wi.vector(), wo.vector());
                } else {
                    throw CLI::RequiredError("--light and --view, or --texel");
                }
                write_image(args->output, image);
                if (!global.quiet)
                    std::printf("wrote %s (%dx%d)\n", args->output.c_str(), image.width(),
                                image.height());
            }};
}

}  // namespace btf::cli
