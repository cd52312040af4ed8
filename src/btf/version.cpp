// SPDX-License-Identifier: MIT
#include "btf/version.h"

// BTFKIT_VERSION is defined for this file only (CMakeLists.txt), so that a new version
// recompiles one file.
#ifndef BTFKIT_VERSION
#error "BTFKIT_VERSION is not defined: build btfkit with its CMakeLists.txt"
#endif

namespace btf {

const char* version() {
    return BTFKIT_VERSION;
}

std::string writer_name() {
    return std::string("btfkit ") + BTFKIT_VERSION;
}

}  // namespace btf
