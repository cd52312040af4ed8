// SPDX-License-Identifier: MIT
// UBO2003 materials as zip archives (io/ubo2003.h): ubo2003::open() of any bytes as an archive
// (written to a scratch file: the reader takes a path), then a few images read from it.
// Structure-aware mutation (support/zip_mutator.h) keeps the entries' CRCs right, so that changed
// names and image bytes reach the reader and the image decoder rather than libzip's CRC check.
#include "btf/io/ubo2003.h"
#include "fuzz/support/fuzz.h"
#include "fuzz/support/zip_mutator.h"

BTF_FUZZ_ZIP_MUTATOR()

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::filesystem::path path = btf::fuzz::write_scratch("input.zip", {data, size});
    return btf::fuzz::run([&] {
        (void)btf::ubo2003::list_views(path);
        btf::fuzz::exercise(*btf::ubo2003::open(path));
    });
}
