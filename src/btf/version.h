// SPDX-License-Identifier: MIT
#pragma once
/// btfkit's version. It is declared once, in CMakeLists.txt's project(); from there it reaches
/// this function, `btf --version`, the "writer" field of every package header, the Python
/// module's __version__, the CMake package's version and btfkit.pc.

#include <string>

namespace btf {

/// "MAJOR.MINOR.PATCH", e.g. "0.2.0".
const char* version();

/// "btfkit MAJOR.MINOR.PATCH": what a package's header names as its writer.
std::string writer_name();

}  // namespace btf
