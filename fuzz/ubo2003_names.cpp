// SPDX-License-Identifier: MIT
// UBO2003 image names (io/ubo2003.h): a folder made from the input, one file per line named by
// the line (view folders included: "tv000_pv000/00000 tl000 pl000 tv000 pv000.jpg"), each a tiny
// valid image; ubo2003::open() of the folder, then a few images read from it.
#include "btf/io/ubo2003.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::filesystem::path folder = btf::fuzz::image_folder("ubo2003", {data, size}, 3, 400);
    return btf::fuzz::run([&] {
        (void)btf::ubo2003::probe(folder);
        btf::fuzz::exercise(*btf::ubo2003::open(folder));
    });
}
