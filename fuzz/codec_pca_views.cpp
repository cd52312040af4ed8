// SPDX-License-Identifier: MIT
// The pca-views codec's open() on any package (checksums recomputed by the package mutator), then a
// few evaluations of the material it returns.
#include "fuzz/support/fuzz.h"
#include "fuzz/support/package_mutator.h"

BTF_FUZZ_PACKAGE_MUTATOR()

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return btf::fuzz::open_with_codec("pca-views", data, size);
}
