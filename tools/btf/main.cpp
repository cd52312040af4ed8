// btf — the btfkit command. Thin by design: parse arguments, call the library, print.

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "btf/util/error.h"
#include "btf/util/parallel.h"
#include "cli.h"

namespace {
// First SIGINT/SIGTERM: cancel the running operation, which unwinds and removes its temporary
// output. A second one ends the process at once.
extern "C" void on_signal(int signal) {
    btf::Progress::cancel_all();
    std::signal(signal, SIG_DFL);
}

// The arguments as a shell would take them back, single-quoted where needed; the program by its
// name ("btf"), not the path it was started from.
std::string shell_command_line(int argc, char** argv) {
    std::string line;
    for (int i = 0; i < argc; ++i) {
        const std::string arg =
            i == 0 ? std::filesystem::path(argv[0]).filename().string() : argv[i];
        const bool plain =
            !arg.empty() && arg.find_first_not_of(
                                "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                "0123456789_-+=.,:/@%") == std::string::npos;
        if (!line.empty()) line += ' ';
        if (plain) {
            line += arg;
            continue;
        }
        line += '\'';
        for (const char c : arg) line += c == '\'' ? std::string("'\\''") : std::string(1, c);
        line += '\'';
    }
    return line;
}
}  // namespace

int main(int argc, char** argv) {
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    using namespace btf::cli;
    CLI::App app{
        "btf: measured material appearance (Bidirectional Texture Functions) from disk "
        "to pixels"};
    app.require_subcommand(1);
    app.option_defaults()->always_capture_default();
    app.set_version_flag("--version", kVersion);
    GlobalOptions global;
    global.command_line = shell_command_line(argc, argv);
    app.add_option("--threads", global.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(0, 1024));
    app.add_flag("-q,--quiet", global.quiet, "no progress output");

    const std::vector<Command> commands = {
        register_info(app, global),       register_convert(app, global),
        register_synth(app, global),      register_slice(app, global),
        register_compress(app, global),   register_decompress(app, global),
        register_eval(app, global),       register_quality(app, global),
        register_report(app, global),     register_render(app, global),
        register_image_diff(app, global), register_bsvtf(app, global),
        register_bsvtf_sim(app, global),  register_serve(app, global),
        register_bundle(app, global),     register_codecs(app, global),
        register_formats(app, global),
    };

    try {
        app.parse(argc, argv);
        btf::ThreadLimit limit(global.threads);
        for (const Command& command : commands)
            if (command.parser->parsed()) command.run();
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const btf::Cancelled&) {
        std::fprintf(stderr, "btf: cancelled\n");
        return 130;
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "btf: error: %s\n", e.what());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "btf: internal error: %s\n", e.what());
        return 2;
    }
    return 0;
}
