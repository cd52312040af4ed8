// SPDX-License-Identifier: MIT
#include "btf/util/dct8.h"

#include <cmath>

#include "btf/util/error.h"

namespace btf::dct8 {

namespace {

// The orthonormal 8-point DCT-II basis: m[k][n] = c_k cos((2n + 1) k π / 16).
struct Basis {
    double m[8][8];
    Basis() {
        for (int k = 0; k < 8; ++k)
            for (int n = 0; n < 8; ++n)
                m[k][n] = (k == 0 ? std::sqrt(1.0 / 8) : std::sqrt(2.0 / 8)) *
                          std::cos((2 * n + 1) * k * M_PI / 16);
    }
};
const Basis kBasis;

}  // namespace

const int kZigZag[64] = {0,  1,  8,  16, 9,  2,  3,  10, 17, 24, 32, 25, 18, 11, 4,  5,
                         12, 19, 26, 33, 40, 48, 41, 34, 27, 20, 13, 6,  7,  14, 21, 28,
                         35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51,
                         58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63};

void forward(const double in[64], double out[64]) {
    double tmp[64];
    for (int r = 0; r < 8; ++r)
        for (int k = 0; k < 8; ++k) {
            double s = 0;
            for (int n = 0; n < 8; ++n) s += kBasis.m[k][n] * in[r * 8 + n];
            tmp[r * 8 + k] = s;
        }
    for (int c = 0; c < 8; ++c)
        for (int k = 0; k < 8; ++k) {
            double s = 0;
            for (int n = 0; n < 8; ++n) s += kBasis.m[k][n] * tmp[n * 8 + c];
            out[k * 8 + c] = s;
        }
}

void inverse(const double in[64], double out[64]) {
    double tmp[64];
    for (int c = 0; c < 8; ++c)
        for (int n = 0; n < 8; ++n) {
            double s = 0;
            for (int k = 0; k < 8; ++k) s += kBasis.m[k][n] * in[k * 8 + c];
            tmp[n * 8 + c] = s;
        }
    for (int r = 0; r < 8; ++r)
        for (int n = 0; n < 8; ++n) {
            double s = 0;
            for (int k = 0; k < 8; ++k) s += kBasis.m[k][n] * tmp[r * 8 + k];
            out[r * 8 + n] = s;
        }
}

void put_varint(std::vector<uint8_t>& out, int64_t v) {
    uint64_t z = (uint64_t(v) << 1) ^ uint64_t(v >> 63);
    while (z >= 0x80) {
        out.push_back(uint8_t(z | 0x80));
        z >>= 7;
    }
    out.push_back(uint8_t(z));
}

int64_t get_varint(const uint8_t*& p, const uint8_t* end, std::string_view what) {
    uint64_t z = 0;
    for (int shift = 0; shift < 64; shift += 7) {
        if (p == end) fail("{}: the coefficients end early", what);
        const uint8_t b = *p++;
        z |= uint64_t(b & 0x7f) << shift;
        if (!(b & 0x80)) return int64_t(z >> 1) ^ -int64_t(z & 1);
    }
    fail("{}: a coefficient is longer than 64 bits", what);
}

}  // namespace btf::dct8
