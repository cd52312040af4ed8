#pragma once
// Shared pieces of the `btf` command: global options, the progress bar, argument parsing.

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

#include "btf/core/direction.h"
#include "btf/io/open.h"
#include "btf/util/progress.h"

namespace btf::cli {

struct GlobalOptions {
    int threads = 0;     // 0 = all cores
    bool quiet = false;  // no progress output
};

/// A Progress that draws a bar on a terminal (stderr) and prints plain lines otherwise.
Progress make_progress(const GlobalOptions& options);

/// "θ,φ" in degrees → Direction; throws btf::Error naming the option on bad input.
Direction parse_direction(const std::string& text, const std::string& option);
/// "x,y" → two integers.
std::pair<int, int> parse_pair(const std::string& text, const std::string& option);
/// "1,5,7" → indices.
std::vector<int> parse_indices(const std::string& text, const std::string& option);

/// 1536 → "1.5 KiB".
std::string human_bytes(double bytes);

/// Adds --views and --raw to a subcommand and returns the OpenOptions they fill.
void add_open_options(CLI::App& command, OpenOptions& options, std::string& views_text);
OpenOptions finish_open_options(OpenOptions options, const std::string& views_text);

/// A subcommand: its CLI11 parser and what to run once arguments are parsed.
struct Command {
    CLI::App* parser = nullptr;
    std::function<void()> run;
};

// One function per subcommand file: declares the options, returns the command.
Command register_info(CLI::App& app, GlobalOptions& global);
Command register_convert(CLI::App& app, GlobalOptions& global);
Command register_synth(CLI::App& app, GlobalOptions& global);
Command register_slice(CLI::App& app, GlobalOptions& global);
Command register_formats(CLI::App& app, GlobalOptions& global);

}  // namespace btf::cli
