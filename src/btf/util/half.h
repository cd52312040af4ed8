// SPDX-License-Identifier: MIT
#pragma once
/// IEEE half floats stored as their 16 bits (packages, tiles, in-memory samples): conversion with
/// Eigen's half type, rounding to nearest even.

#include <Eigen/Core>

#include <cstdint>

namespace btf {

inline uint16_t to_half(float value) {
    return Eigen::numext::bit_cast<uint16_t>(Eigen::half(value));
}

inline float from_half(uint16_t bits) {
    return static_cast<float>(Eigen::numext::bit_cast<Eigen::half>(bits));
}

}  // namespace btf
