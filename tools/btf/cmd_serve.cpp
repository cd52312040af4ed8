// SPDX-License-Identifier: MIT
// btf serve [PKG|DIR ...] [--port 8080] [--bind 127.0.0.1] [--web DIR]: the materials over HTTP
// and WebSockets for the web viewer (docs/protocol.md) until SIGINT or SIGTERM. Without
// packages it serves the built-in demo material, made once and kept in the cache folder.

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/stream/catalog.h"
#include "btf/stream/server.h"
#include "btf/synth/synth.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace fs = std::filesystem;

Command register_serve(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::vector<std::string> inputs;
        int port = 8080;
        std::string bind = "127.0.0.1", web;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd =
        app.add_subcommand("serve",
                           "Serve compressed materials to the web viewer over HTTP and WebSockets "
                           "(docs/protocol.md) until Ctrl-C");
    cmd->add_option("inputs", args->inputs,
                    "btfkit packages (*.btfpkg, *.bsvtf), UBO2014 .btf files or folders of "
                    "packages; none: the built-in demo "
                    "material (woven_fabric, made once into the cache folder: $BTF_CACHE_DIR, "
                    "$XDG_CACHE_HOME/btfkit or ~/.cache/btfkit)");
    cmd->add_option("--port", args->port, "TCP port (0: any free port)")
        ->check(CLI::Range(0, 65535));
    cmd->add_option("--bind", args->bind, "address to listen on (0.0.0.0: every interface)");
    cmd->add_option("--web", args->web,
                    "the web viewer's folder (default: the installed viewer, "
                    "PREFIX/share/btfkit/web beside PREFIX/bin/btf, else the build's own)");

    return {cmd, [args, &global] {
                stream::ServerOptions options;
                options.bind = args->bind;
                options.port = static_cast<uint16_t>(args->port);
                options.threads = global.threads;
                if (!args->web.empty()) {
                    std::error_code ec;
                    if (!fs::is_directory(args->web, ec))
                        fail("{}: --web: no such folder", args->web);
                    options.web_root = args->web;
                } else {
                    // Until the viewer is built, `/` shows the built-in page.
                    options.web_root = default_web_dir();
                }
                std::vector<fs::path> inputs = servable_inputs(args->inputs, global);
                if (inputs.empty()) inputs.push_back(demo_package(global));
                stream::Catalog catalog = stream::Catalog::build(inputs);
                const size_t count = catalog.size();
                stream::Server server(std::move(catalog), options);

                // The handlers go in before the address is announced: whoever reads the line may
                // signal at once.
                boost::asio::io_context signals_context;
                boost::asio::signal_set signals(signals_context, SIGINT, SIGTERM);
                signals.async_wait([](const boost::system::error_code&, int) {});
                server.start();
                std::printf("serving %zu material%s at %s\n", count, count == 1 ? "" : "s",
                            server.url().c_str());
                std::fflush(stdout);
                // A signal that came before the handlers were installed went to main()'s handler.
                if (!Progress::all_cancelled()) signals_context.run();
                // Removing the handlers restores the default action: a second Ctrl-C during the
                // shutdown grace period ends the process at once.
                signals.clear();
                server.stop();
            }};
}

}  // namespace btf::cli
