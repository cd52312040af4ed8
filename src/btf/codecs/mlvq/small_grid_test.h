// SPDX-License-Identifier: MIT
#pragma once
/// The small mlvq grid of the codec's tests: 7 α × 7 β × 4 θv (0°, 30°, 60°, 90°) × 6 φv (60°
/// apart). It keeps the tests fast; the structure is the paper's.

#include "btf/codecs/codec.h"

namespace btf::mlvq {

inline Params small_grid(Params p = {}) {
    p.set("n-alpha", "7");
    p.set("n-beta", "7");
    p.set("n-theta-v", "4");
    p.set("n-phi-v", "6");
    return p;
}

}  // namespace btf::mlvq
