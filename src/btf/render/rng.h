// SPDX-License-Identifier: MIT
#pragma once
/// The renderer's random numbers: PCG32 (O'Neill 2014), one stream per (seed, pixel, sample) so
/// that an image is the same for any number of threads and any tile order.

#include <cstdint>

namespace btf::render {

class Rng {
  public:
    /// The stream for sample `index` of pixel `pixel` under `seed`.
    Rng(uint64_t seed, uint64_t pixel, uint64_t index) {
        m_inc = (mix(pixel * 0x9E3779B97F4A7C15ull ^ index) << 1) | 1;
        m_state = 0;
        next();
        m_state += mix(seed ^ (index * 0xD1B54A32D192ED03ull));
        next();
    }
    uint32_t next() {
        const uint64_t old = m_state;
        m_state = old * 6364136223846793005ull + m_inc;
        const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
        const uint32_t rot = uint32_t(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((32 - rot) & 31));
    }
    /// Uniform in [0, 1).
    double uniform() { return double(next()) * 0x1p-32; }

  private:
    // SplitMix64's finalizer: decorrelates neighbouring pixels and sample indices.
    static uint64_t mix(uint64_t z) {
        z += 0x9E3779B97F4A7C15ull;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    uint64_t m_state = 0, m_inc = 1;
};

}  // namespace btf::render
