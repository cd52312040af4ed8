// SPDX-License-Identifier: MIT
// UTIA image-set names (io/utia.h): a folder made from the input, one file per line named by the
// line ("tl045_pl020_tv000_pv000.png"), each a tiny valid image; utia::open() of the folder, then
// a few images read from it.
#include "btf/io/utia.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::filesystem::path folder = btf::fuzz::image_folder("utia", {data, size}, 1, 400);
    return btf::fuzz::run([&] {
        (void)btf::utia::probe(folder);
        btf::fuzz::exercise(*btf::utia::open(folder));
    });
}
