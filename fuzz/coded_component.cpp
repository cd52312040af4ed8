// SPDX-License-Identifier: MIT
// The coded factor decoder (codecs/factor/coded.h): get_component() on any payload, for a shape
// chosen by the first two bytes: a's rows (1–96, so rows of 3 channels and others) and b either
// an image of 1–16 × 1–16 texels or, with the high bit of the second byte, as many plain values.
// a's rows are laid out as directions (coded.h, AngularRows): 3 channels when the rows are a
// multiple of 3, else 1, and the most lights of 9, 3 and 1 that divide the (view, light) pairs.
#include <vector>

#include "btf/codecs/factor/coded.h"
#include "fuzz/support/fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 2) return 0;
    return btf::fuzz::run([&] {
        namespace coded = btf::factor::coded;
        const int rows = 1 + data[0] % 96;
        const int width = 1 + (data[1] & 15), height = 1 + ((data[1] >> 4) & 7);
        const bool image = (data[1] & 128) == 0;
        const int channels = rows % 3 == 0 ? 3 : 1;
        const int lights = (rows / channels) % 9 == 0 ? 9 : (rows / channels) % 3 == 0 ? 3 : 1;
        std::vector<float> a(static_cast<size_t>(rows)), b(static_cast<size_t>(width * height));
        coded::get_component(data + 2, size - 2, {a.data(), rows, 1}, {b.data(), width * height, 1},
                             image ? coded::Image{width, height} : coded::Image{}, "b0.k0",
                             {lights, channels});
    });
}
