// SPDX-License-Identifier: MIT
#include "btf/util/range_coder.h"

#include <algorithm>

#include "btf/util/error.h"

namespace btf::range {

namespace {
constexpr int kProbabilityBits = 11;
constexpr int kAdaptShift = 5;
constexpr uint32_t kTop = 1u << 24;
constexpr uint16_t kOne = 1u << kProbabilityBits;
}  // namespace

void Encoder::bit(uint16_t& p, int bit) {
    const uint32_t bound = (m_range >> kProbabilityBits) * p;
    if (bit == 0) {
        m_range = bound;
        p = uint16_t(p + ((kOne - p) >> kAdaptShift));
    } else {
        m_low += bound;
        m_range -= bound;
        p = uint16_t(p - (p >> kAdaptShift));
    }
    while (m_range < kTop) {
        m_range <<= 8;
        shift_low();
    }
}

void Encoder::direct(uint64_t v, int bits) {
    for (int i = bits - 1; i >= 0; --i) {
        m_range >>= 1;
        if ((v >> i) & 1) m_low += m_range;
        while (m_range < kTop) {
            m_range <<= 8;
            shift_low();
        }
    }
}

// Moves the top byte of the 32-bit low end out. A byte is held back while a carry could still
// reach it: the cache, and any 0xFF bytes after it, which a carry turns into 0x00.
void Encoder::shift_low() {
    if (uint32_t(m_low) < 0xFF000000u || (m_low >> 32) != 0) {
        const auto carry = uint8_t(m_low >> 32);
        uint8_t held = m_cache;
        do {
            m_out.push_back(uint8_t(held + carry));
            held = 0xFF;
        } while (--m_pending != 0);
        m_cache = uint8_t(m_low >> 24);
    }
    ++m_pending;
    m_low = (m_low & 0x00FFFFFFu) << 8;
}

std::vector<uint8_t> Encoder::finish() {
    for (int i = 0; i < 5; ++i) shift_low();
    return std::move(m_out);
}

Decoder::Decoder(const uint8_t* data, size_t size, std::string_view what)
    : m_p(data), m_end(data + size), m_what(what) {
    for (int i = 0; i < 5; ++i) m_code = (m_code << 8) | next();
}

uint8_t Decoder::next() {
    if (m_p == m_end) fail("{}: the coded factors end early", m_what);
    return *m_p++;
}

int Decoder::bit(uint16_t& p) {
    const uint32_t bound = (m_range >> kProbabilityBits) * p;
    int bit;
    if (m_code < bound) {
        m_range = bound;
        p = uint16_t(p + ((kOne - p) >> kAdaptShift));
        bit = 0;
    } else {
        m_code -= bound;
        m_range -= bound;
        p = uint16_t(p - (p >> kAdaptShift));
        bit = 1;
    }
    while (m_range < kTop) {
        m_range <<= 8;
        m_code = (m_code << 8) | next();
    }
    return bit;
}

uint64_t Decoder::direct(int bits) {
    uint64_t v = 0;
    for (int i = 0; i < bits; ++i) {
        m_range >>= 1;
        int bit = 0;
        if (m_code >= m_range) {
            m_code -= m_range;
            bit = 1;
        }
        v = (v << 1) | uint64_t(bit);
        while (m_range < kTop) {
            m_range <<= 8;
            m_code = (m_code << 8) | next();
        }
    }
    return v;
}

IntegerModel::IntegerModel(int contexts) : m_contexts(size_t(contexts)) {}

void IntegerModel::put(Encoder& coder, int context, int64_t v) {
    Context& c = m_contexts[size_t(context)];
    Set& s = c.set();
    const uint64_t m = v < 0 ? uint64_t(0) - uint64_t(v) : uint64_t(v);
    coder.bit(s.zero, m != 0);
    if (m != 0) {
        coder.direct(v < 0 ? 1 : 0, 1);
        const int k = 63 - __builtin_clzll(m);
        for (int i = 0; i < k; ++i)
            coder.bit(s.unary[size_t(std::min(i, kClassProbabilities - 1))], 1);
        coder.bit(s.unary[size_t(std::min(k, kClassProbabilities - 1))], 0);
        coder.direct(m, k);  // the bits under the leading one
    }
    c.last = int(std::min<uint64_t>(m, 3));
}

int64_t IntegerModel::get(Decoder& coder, int context) {
    Context& c = m_contexts[size_t(context)];
    Set& s = c.set();
    int64_t v = 0;
    uint64_t m = 0;
    if (coder.bit(s.zero) != 0) {
        const bool negative = coder.direct(1) != 0;
        int k = 0;
        while (coder.bit(s.unary[size_t(std::min(k, kClassProbabilities - 1))]) != 0)
            if (++k > 62) fail("{}: a coded value is longer than 64 bits", coder.what());
        m = (uint64_t(1) << k) | coder.direct(k);
        v = negative ? -int64_t(m) : int64_t(m);
    }
    c.last = int(std::min<uint64_t>(m, 3));
    return v;
}

}  // namespace btf::range
