// SPDX-License-Identifier: MIT
// BTF_CLONES: a hot function compiled for three x86-64 levels, the loader choosing one for the
// processor it runs on (GCC's function multi-versioning: an ifunc, resolved once at load time).
//
//   default    the build's own target (the x86-64 baseline: SSE2)
//   x86-64-v3  AVX2, FMA, F16C (Intel Haswell, AMD Excavator and later)
//   x86-64-v4  AVX-512 F/BW/CD/DQ/VL (Intel Skylake-SP, AMD Zen 4 and later)
//
// `flatten` inlines every call the function makes into code of this translation unit, so the
// helpers it calls run in the clone's instructions too; calls into other translation units run
// their own code (a hot one there gets BTF_CLONES of its own). GCC cannot clone a virtual
// function: put the attribute on the non-virtual function a virtual one calls.
//
// Only in a build for less than x86-64-v3 (the Debian package, the `package` preset): a
// -march=native build (`make`) compiles once, for its machine, and its code paths chosen by
// preprocessor (__AVX2__, __F16C__) stay as they are. Inside a clone those macros keep the build's
// values, so intrinsics a clone should use go in a helper compiled for them by attribute
// (target("avx,f16c")), called behind __builtin_cpu_supports("x86-64-v3"), which is constant
// within each clone (factor/material.cpp's half-float loads do this).
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__ELF__) && \
    !defined(__AVX2__) && !defined(BTF_NO_CLONES)
#define BTF_CLONES \
    __attribute__((target_clones("default", "arch=x86-64-v3", "arch=x86-64-v4"), flatten))
#define BTF_HAS_CLONES 1
#else
#define BTF_CLONES
#define BTF_HAS_CLONES 0
#endif

namespace btf {

/// The code BTF_CLONES functions run in this process: "x86-64-v4 clones", "x86-64-v3 clones" or
/// "x86-64 clones" (the default one) in a build with clones, else "one build for its target"
/// (`btf --verbose` says it).
const char* clone_level();

}  // namespace btf
