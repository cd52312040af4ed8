// SPDX-License-Identifier: MIT
// btf slice FILE --light θ,φ --view θ,φ -o img.png   |   btf slice FILE --texel x,y -o abrdf.png

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

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
    cmd->add_option("file", args->path, "BTF file or folder, or a btfkit package")->required();
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

    return {
        cmd, [args, &global] {
            // Check the arguments before opening: opening a large archive takes time.
            std::optional<std::pair<int, int>> texel;
            Direction wi, wo;
            if (!args->texel.empty()) {
                texel = parse_pair(args->texel, "--texel");
            } else if (!args->light.empty()) {
                wi = parse_direction(args->light, "--light");
                wo = parse_direction(args->view, "--view");
            } else {
                throw CLI::RequiredError("--light and --view, or --texel");
            }
            const auto source = open_input(args->path, args->open, args->views);
            Image image;
            if (texel) {
                Progress progress = make_progress(global);
                image = abrdf_image(*source, texel->first, texel->second, args->scale, progress);
            } else {
                image = slice_image(*source, wi.vector(), wo.vector());
                // A partial material (or a sparse direction set) can only repeat what it
                // has: say so when the nearest measured direction is far away.
                auto warn_if_far = [](const DirectionSet& set, const Direction& d,
                                      const char* what) {
                    const int i = set.nearest(d.vector());
                    const double angle =
                        degrees(std::acos(std::clamp(dot(set.vector(i), d.vector()), -1.0, 1.0)));
                    if (angle > 20)
                        std::fprintf(stderr,
                                     "btf: note: the nearest measured %s (%.1f, %.1f) is "
                                     "%.0f degrees from the requested one; the image is "
                                     "extrapolated from the %d measured %ss\n",
                                     what, set[i].theta_deg(), set[i].phi_deg(), angle, set.size(),
                                     what);
                };
                warn_if_far(source->sampling().views, wo, "view");
                warn_if_far(source->sampling().lights, wi, "light");
            }
            write_image(args->output, image);
            if (!global.quiet)
                std::printf("wrote %s (%dx%d)\n", args->output.c_str(), image.width(),
                            image.height());
        }};
}

}  // namespace btf::cli
