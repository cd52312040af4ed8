// SPDX-License-Identifier: MIT
// btf eval PKG --uv u,v --light θ,φ --view θ,φ: one BTF value (linear RGB), interpolated; or
// btf eval PKG --queries FILE: one value per line of FILE ("u,v θi,φi θo,φo"; - = stdin).

#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/io/ubo2014.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

void print(const Rgb& rgb) {
    std::printf("%.6g %.6g %.6g\n", rgb.r, rgb.g, rgb.b);
}

// Evaluates every query of `in` (named `name` in errors): one per line, the three fields of
// --uv, --light and --view separated by white space; empty lines and lines starting with # are
// skipped. Nothing is printed unless every line parses.
void eval_queries(const Material& material, std::istream& in, const std::string& name) {
    std::vector<Query> queries;
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
        std::istringstream fields(line);
        std::string uv, light, view, extra;
        if (!(fields >> uv) || uv.front() == '#') continue;
        const std::string where = fmt::format("{}: line {}", name, number);
        if (!(fields >> light >> view) || (fields >> extra))
            fail("{}: expected 'u,v theta,phi theta,phi' (uv, light, view), got '{}'", where, line);
        queries.push_back({parse_uv(uv, where), parse_direction(light, where).vector(),
                           parse_direction(view, where).vector()});
    }
    if (in.bad()) fail("{}: cannot be read", name);
    for (const Query& q : queries) print(material.eval(q.uv, q.wi, q.wo));
}

}  // namespace

Command register_eval(CLI::App& app, GlobalOptions&) {
    struct Args {
        std::string path, uv, light, view, queries;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand("eval",
                                       "Print the linear RGB value of a compressed material "
                                       "(btfkit package, BSVTF file or UBO2014 .btf) at a texture "
                                       "position and any light and view direction");
    cmd->add_option("file", args->path,
                    "btfkit package (.btfpkg), BSVTF file (.bsvtf) or UBO2014 .btf")
        ->required();
    CLI::Option* uv = cmd->add_option("--uv", args->uv,
                                      "texture position 'u,v' (wraps; 0,0 = first texel's corner)");
    CLI::Option* light =
        cmd->add_option("--light", args->light, "light direction 'theta,phi' in degrees");
    CLI::Option* view =
        cmd->add_option("--view", args->view, "view direction 'theta,phi' in degrees");
    CLI::Option* queries =
        cmd->add_option("--queries", args->queries,
                        "many queries instead: a file (- for stdin) with one 'u,v theta,phi "
                        "theta,phi' (uv, light, view) per line; prints one line each");
    uv->needs(light, view)->excludes(queries);
    light->needs(uv, view)->excludes(queries);
    view->needs(uv, light)->excludes(queries);

    return {cmd, [args] {
                if (args->queries.empty() && args->uv.empty())
                    fail("eval: give --uv, --light and --view, or --queries");
                Query query;
                if (args->queries.empty())
                    query = {parse_uv(args->uv, "--uv"),
                             parse_direction(args->light, "--light").vector(),
                             parse_direction(args->view, "--view").vector()};
                const std::unique_ptr<Material> material = open_material_file(args->path);
                if (args->queries == "-") {
                    eval_queries(*material, std::cin, "stdin");
                } else if (!args->queries.empty()) {
                    std::ifstream in(args->queries);
                    if (!in) fail("{}: cannot be opened", args->queries);
                    eval_queries(*material, in, args->queries);
                } else {
                    print(material->eval(query.uv, query.wi, query.wo));
                }
            }};
}

}  // namespace btf::cli
