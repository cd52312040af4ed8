// SPDX-License-Identifier: MIT
// btf codecs: the compression codecs in this build and their parameters.

#include <algorithm>
#include <cstdio>

#include "btf/codecs/codec.h"
#include "cli.h"

namespace btf::cli {

Command register_codecs(CLI::App& app, GlobalOptions&) {
    CLI::App* cmd = app.add_subcommand(
        "codecs", "List the compression codecs of this build with their parameters (-p key=value)");
    return {cmd, [] {
                bool first = true;
                for (const Codec* codec : codecs()) {
                    if (!first) std::printf("\n");
                    first = false;
                    const std::string name(codec->name()), description(codec->description());
                    std::printf("%s  %s\n", name.c_str(), description.c_str());
                    const std::vector<ParamInfo> params = codec->params();
                    // "key=default" is what -p takes, so the default reads as an example.
                    size_t width = 0;
                    for (const ParamInfo& p : params)
                        width = std::max(width, p.name.size() + 1 + p.default_value.size());
                    for (const ParamInfo& p : params) {
                        const std::string item = p.name + "=" + p.default_value;
                        // Numbers show their range; choices and flags list their values in the
                        // help already.
                        const std::string range =
                            p.type == "int" || p.type == "number" ? " [" + p.range + "]" : "";
                        std::printf("    %-*s  %s%s\n", int(width), item.c_str(), p.help.c_str(),
                                    range.c_str());
                    }
                }
            }};
}

}  // namespace btf::cli
