// SPDX-License-Identifier: MIT
#pragma once
// Test support (GoogleTest only; not part of the library): runs the `btf` command the way a user
// does and returns its exit code and everything it printed. A test including this header makes
// CMake build the command before the test (see CMakeLists.txt).

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace btf::test {

struct CliResult {
    int code = -1;
    std::string output;  // stdout and stderr together
};

/// Runs shell text `command` (its stderr joined to its stdout).
inline CliResult run_shell(const std::string& command);

/// Runs `btf --quiet ARGS` through the shell (ARGS is shell text: quote paths with spaces), after
/// the shell commands `setup` when given (e.g. "ulimit -v 3145728").
inline CliResult run(const std::string& args, const std::string& setup = "") {
    return run_shell((setup.empty() ? "" : setup + " && exec ") + std::string(BTF_TOOL_PATH) +
                     " --quiet " + args);
}

inline CliResult run_shell(const std::string& shell_text) {
    const std::string command = shell_text + " 2>&1";
    CliResult result;
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) return result;
    std::array<char, 4096> buffer;
    size_t n;
    while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
        result.output.append(buffer.data(), n);
    const int status = ::pclose(pipe);
    result.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return result;
}

}  // namespace btf::test
