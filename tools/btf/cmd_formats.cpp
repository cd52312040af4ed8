// btf formats: the readers compiled into this build.

#include <cstdio>

#include "cli.h"

namespace btf::cli {

Command register_formats(CLI::App& app, GlobalOptions&) {
    CLI::App* cmd = app.add_subcommand("formats", "List the BTF formats this build reads");
    return {cmd, [] {
                for (const Reader& reader : readers())
                    std::printf("%-10s %s\n", reader.name.c_str(), reader.description.c_str());
            }};
}

}  // namespace btf::cli
