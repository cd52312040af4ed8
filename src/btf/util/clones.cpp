// SPDX-License-Identifier: MIT
#include "btf/util/clones.h"

namespace btf {

const char* clone_level() {
#if BTF_HAS_CLONES
    // The tests of GCC's resolver for the clones' arch=x86-64-v4 and arch=x86-64-v3.
    if (__builtin_cpu_supports("x86-64-v4")) return "x86-64-v4 clones";
    if (__builtin_cpu_supports("x86-64-v3")) return "x86-64-v3 clones";
    return "x86-64 clones";
#else
    return "one build for its target";
#endif
}

}  // namespace btf
