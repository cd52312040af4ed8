// SPDX-License-Identifier: MIT
// btf — the btfkit command. Thin by design: parse arguments, call the library, print.

#include <poll.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "btf/util/atomic_file.h"
#include "btf/util/blas.h"
#include "btf/util/clones.h"
#include "btf/util/error.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"
#include "btf/util/thin_products.h"
#include "cli.h"
#include "mpi_world.h"

namespace {
// SIGINT/SIGTERM cancel the running operation, which unwinds and removes its temporary output.
// The handler only sets the flag and wakes the watchdog thread (both async-signal-safe); the
// watchdog guarantees the promise of docs/reliability.md whatever the operation is doing: if the
// process has not ended within kCancelGraceMs of the first signal (a library call that does not
// look at the flag), or at a second signal, it removes every temporary output and exits 130.
constexpr int kCancelGraceMs = 500;
int g_signal_pipe[2] = {-1, -1};

extern "C" void on_signal(int) {
    btf::Progress::cancel_all();
    const char byte = 1;
    [[maybe_unused]] const ssize_t n = ::write(g_signal_pipe[1], &byte, 1);
}

void watchdog() {
    char byte;
    while (::read(g_signal_pipe[0], &byte, 1) != 1) {
    }
    pollfd second{g_signal_pipe[0], POLLIN, 0};
    ::poll(&second, 1, kCancelGraceMs);
    btf::AtomicOutput::remove_all_temporaries();
    static const char message[] = "btf: cancelled\n";
    [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, message, sizeof message - 1);
    ::_exit(130);
}

void install_signal_handlers() {
    if (::pipe(g_signal_pipe) != 0) return;  // no watchdog: cancellation stays cooperative
    std::thread(watchdog).detach();
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
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

// Under MPI, a failure only this rank saw (not agreed by every rank) must end the others, which
// may be waiting for this one in a collective operation.
int failed(int code) {
    if (btf::cli::mpi_world() && !btf::cli::failure_agreed()) btf::cli::abort_world(code);
    return code;
}

int run(int argc, char** argv);
}  // namespace

int main(int argc, char** argv) {
    install_signal_handlers();
    std::unique_ptr<btf::cli::MpiSession> mpi;
    try {
        mpi = std::make_unique<btf::cli::MpiSession>();
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "btf: error: %s\n", e.what());
        return 1;
    }
    return run(argc, argv);
}

namespace {
int run(int argc, char** argv) {
    using namespace btf::cli;
    CLI::App app{
        "btf: measured material appearance (Bidirectional Texture Functions) from disk "
        "to pixels"};
    app.require_subcommand(1);
    app.option_defaults()->always_capture_default();
    app.set_version_flag("--version", version_line());
    GlobalOptions global;
    global.command_line = shell_command_line(argc, argv);
    app.add_option("--threads", global.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(0, 1024));
    app.add_flag("-q,--quiet", global.quiet, "no progress output");
    bool verbose = false;
    app.add_flag("-v,--verbose", verbose,
                 "say on stderr what runs the factorization's products (btfkit's AVX-512 "
                 "kernels or OpenBLAS, and which OpenBLAS kernel) and how many worker threads "
                 "run");
    int64_t max_image_pixels = 0;
    std::string max_alloc;
    app.add_option("--max-image-pixels", max_image_pixels,
                   "largest image (width x height texels) an input may hold or declare (default "
                   "67108864 = 8192x8192, or $BTF_MAX_IMAGE_PIXELS)")
        ->check(CLI::PositiveNumber);
    app.add_option("--max-alloc", max_alloc,
                   "largest single allocation for what an input declares, e.g. 8G or 512M "
                   "(default 4G, or $BTF_MAX_ALLOC)");
    bool allow_hdf5_external = false;
    app.add_flag("--allow-hdf5-external", allow_hdf5_external,
                 "let HDF5 inputs read other files (external links, external storage, virtual "
                 "datasets; or $BTF_ALLOW_HDF5_EXTERNAL=1)");

    const std::vector<Command> commands = {
        register_info(app, global),          register_convert(app, global),
        register_synth(app, global),         register_slice(app, global),
        register_compress(app, global),      register_decompress(app, global),
        register_eval(app, global),          register_quality(app, global),
        register_report(app, global),        register_render(app, global),
        register_image_diff(app, global),    register_bsvtf(app, global),
        register_bsvtf_sim(app, global),     register_serve(app, global),
        register_bundle(app, global),        register_codecs(app, global),
        register_compress_many(app, global), register_formats(app, global),
        register_bench(app, global),         register_manpage(app, global),
    };

    try {
        app.parse(argc, argv);
        btf::Limits limits = btf::limits();
        if (max_image_pixels > 0) limits.image_pixels = max_image_pixels;
        if (!max_alloc.empty()) {
            const auto bytes = btf::parse_limit_bytes(max_alloc);
            if (!bytes)
                btf::fail("--max-alloc {}: expected a byte count such as 8G or 512M", max_alloc);
            limits.alloc_bytes = *bytes;
        }
        if (allow_hdf5_external) limits.allow_hdf5_external = true;
        btf::set_limits(limits);
        btf::ThreadLimit limit(global.threads);
        if (verbose)
            std::fprintf(stderr,
                         "btf: %d worker threads; evaluators: %s; factorization products: %s; %s\n",
                         btf::worker_threads(), btf::clone_level(),
                         btf::thin::kernel() == btf::thin::Kernel::kOwn ? "btfkit's AVX-512 kernels"
                                                                        : "OpenBLAS",
                         btf::blas::description().c_str());
        for (const Command& command : commands) {
            if (!command.parser->parsed()) continue;
            const std::string name = command.parser->get_name();
            if (mpi_world() && name != "compress" && name != "compress-many") {
                const std::string error = fmt::format(
                    "btf {} runs in one process: start it without mpirun (compress and "
                    "compress-many run across ranks)",
                    name);
                agree_everywhere(error);
                throw btf::Error(error);
            }
            command.run();
        }
    } catch (const CLI::ParseError& e) {
        agree_everywhere(e.what());
        return failed(app.exit(e));
    } catch (const btf::Cancelled&) {
        std::fprintf(stderr, "btf: cancelled\n");
        return failed(130);
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "btf: error: %s\n", e.what());
        return failed(1);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "btf: internal error: %s\n", e.what());
        return failed(2);
    }
    return 0;
}
}  // namespace
