// SPDX-License-Identifier: MIT
// btfkit HDF5 files (io/h5.h) from an in-memory image: h5::open_memory() of any bytes, then a
// few images read from the source.
#include "btf/io/h5.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return btf::fuzz::run([&] {
        const auto source =
            btf::h5::open_memory(std::vector<uint8_t>(data, data + size), "input.h5");
        btf::fuzz::exercise(*source);
    });
}
