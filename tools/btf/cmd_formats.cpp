// SPDX-License-Identifier: MIT
// btf formats: the readers compiled into this build.

#include <cstdio>
#include <string>

#include "btf/core/image.h"
#include "btf/util/error.h"

#include "cli.h"

namespace btf::cli {

Command register_formats(CLI::App& app, GlobalOptions&) {
    CLI::App* cmd = app.add_subcommand("formats", "List the BTF formats this build reads");
    return {cmd, [] {
                for (const Reader& reader : readers())
                    std::printf("%-10s %s\n", reader.name.c_str(), reader.description.c_str());
                // Pictures (UBO2003 JPEGs, UTIA images, PNG/EXR output) go through the image
                // module; where it was found tells an installed tree from a build tree.
                std::string module;
                try {
                    module = "OpenImageIO through " + image_module_path();
                } catch (const Error& e) {
                    module = std::string("not available: ") + e.what();
                }
                std::printf("\nimages     %s\n", module.c_str());
            }};
}

}  // namespace btf::cli
