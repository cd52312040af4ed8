// btf eval PKG --uv u,v --light θ,φ --view θ,φ: one BTF value (linear RGB), interpolated.

#include <cstdio>

#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/io/ubo2014.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

Command register_eval(CLI::App& app, GlobalOptions&) {
    struct Args {
        std::string path, uv, light, view;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand("eval",
                                       "Print the linear RGB value of a compressed material "
                                       "(btfkit package, BSVTF file or UBO2014 .btf) at a texture "
                                       "position and any light and view direction");
    cmd->add_option("file", args->path,
                    "btfkit package (.btfpkg), BSVTF file (.bsvtf) or UBO2014 .btf")
        ->required();
    cmd->add_option("--uv", args->uv, "texture position 'u,v' (wraps; 0,0 = first texel's corner)")
        ->required();
    cmd->add_option("--light", args->light, "light direction 'theta,phi' in degrees")->required();
    cmd->add_option("--view", args->view, "view direction 'theta,phi' in degrees")->required();

    return {cmd, [args] {
                const Uv uv = parse_uv(args->uv, "--uv");
                const Direction wi = parse_direction(args->light, "--light");
                const Direction wo = parse_direction(args->view, "--view");
                std::unique_ptr<Material> material;
                if (probe_package(args->path))
                    material = open_material(std::filesystem::path(args->path));
                else if (ubo2014::probe(args->path))
                    material = ubo2014::open_material(args->path);
                else if (!std::filesystem::exists(args->path))
                    fail("{}: no such file", args->path);
                else
                    fail("{}: not a btfkit package or UBO2014 .btf file", args->path);
                const Rgb rgb = material->eval(uv, wi.vector(), wo.vector());
                std::printf("%.6g %.6g %.6g\n", rgb.r, rgb.g, rgb.b);
            }};
}

}  // namespace btf::cli
