// SPDX-License-Identifier: MIT
#pragma once
/// An adaptive binary range coder and the model of signed integers that btfkit's coded factor
/// storage writes with it (docs/formats.md, "Coded components"). Everything is integer arithmetic
/// in a fixed order, so that the viewer's decoder (web/src/rangecoder.ts) reads the same bytes
/// to the same numbers.
///
/// The coder: a 32-bit range split by 11-bit probabilities (the probability of a 0), adapted by
/// 1/32 of the distance to 0 or 2048 after each bit; equiprobable ("direct") bits halve the
/// range. The encoder keeps a 33-bit low end and carries into the bytes it holds back; after its
/// last bit it writes 5 bytes, so that the decoder, which starts by reading 5, reads every byte
/// and no more.
///
/// The integer model: per context, a flag for zero, and for a non-zero value its sign (direct),
/// the Exp-Golomb class k = ⌊log₂|v|⌋ in unary (k ones then a zero, each bit adaptive: bit i
/// with probability i, or 23 from i = 23 on) and the k bits of |v| under its leading one
/// (direct, most significant first). The flag and the unary bits are chosen among three sets by
/// the magnitude of the previous value in the same context: 0, 1–2, or more.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace btf::range {

class Encoder {
  public:
    /// One bit under the adaptive probability p (of a 0, out of 2048), which it updates.
    void bit(uint16_t& p, int bit);
    /// The low `bits` bits of v (at most 64), most significant first, each with probability 1/2.
    void direct(uint64_t v, int bits);
    /// The coded bytes (the coder cannot be used afterwards).
    std::vector<uint8_t> finish();

  private:
    void shift_low();
    uint64_t m_low = 0;
    uint32_t m_range = 0xFFFFFFFFu;
    uint8_t m_cache = 0;
    uint64_t m_pending = 1;  // bytes held back: the cache and the 0xFF bytes after it
    std::vector<uint8_t> m_out;
};

class Decoder {
  public:
    /// Reads the first 5 bytes; `what` names the data in errors ("section 'b0.k0'").
    Decoder(const uint8_t* data, size_t size, std::string_view what);
    int bit(uint16_t& p);
    uint64_t direct(int bits);
    /// Bytes not read (0 after decoding everything a matching encoder wrote).
    size_t remaining() const { return size_t(m_end - m_p); }
    const std::string& what() const { return m_what; }

  private:
    uint8_t next();
    const uint8_t* m_p;
    const uint8_t* m_end;
    uint32_t m_range = 0xFFFFFFFFu;
    uint32_t m_code = 0;
    std::string m_what;
};

/// Probabilities start at one half.
constexpr uint16_t kHalf = 1024;

class IntegerModel {
  public:
    explicit IntegerModel(int contexts);
    void put(Encoder& coder, int context, int64_t v);
    /// Throws btf::Error "<what>: a coded value is longer than 64 bits" for a class above 62.
    int64_t get(Decoder& coder, int context);

  private:
    static constexpr int kClassProbabilities = 24;
    struct Set {
        uint16_t zero = kHalf;
        std::array<uint16_t, kClassProbabilities> unary;
        Set() { unary.fill(kHalf); }
    };
    struct Context {
        std::array<Set, 3> sets;
        int last = 0;  // the previous magnitude, at most 3
        Set& set() { return sets[size_t(last == 0 ? 0 : last <= 2 ? 1 : 2)]; }
    };
    std::vector<Context> m_contexts;
};

}  // namespace btf::range
