// SPDX-License-Identifier: MIT
#pragma once
/// Errors in btfkit: the library never prints and never exits; it throws btf::Error whose
/// message names the file, the offset or image, and what was wrong, e.g.
///   "corduroy.btf: byte 112: U matrix declares 151×4 rows×cols but file ends after 3 rows".

#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace btf {

class Error : public std::runtime_error {
  public:
    explicit Error(const std::string& message) : std::runtime_error(message) {}
};

/// Thrown by util::Progress when an operation was cancelled by its caller.
class Cancelled : public Error {
  public:
    Cancelled() : Error("operation cancelled") {}
};

/// Throws btf::Error with a fmt-formatted message.
template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
    throw Error(fmt::format(format, std::forward<Args>(args)...));
}

/// Checks a condition on input data; throws btf::Error with the formatted message if false.
template <typename... Args>
void check(bool condition, fmt::format_string<Args...> format, Args&&... args) {
    if (!condition) throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace btf
