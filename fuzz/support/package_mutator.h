// SPDX-License-Identifier: MIT
#pragma once
/// Structure-aware mutation of btfkit packages (io/package.h). A package carries an XXH64 of its
/// JSON header and one of every section, so nearly every byte-level mutation of a valid package
/// only reaches the checksum test. This mutator parses the layout without checking anything,
/// mutates one part of it and writes the package again with every checksum recomputed:
///
/// - a header value (a number set to an edge value such as 0, −1, 2³¹, 2⁴⁰ or 1.5, a string
///   replaced or mutated, a value of another type) or a header container (an element dropped or
///   duplicated, a key removed or added);
/// - the decoded bytes of one section (libFuzzer's byte mutations, or floats, half floats and
///   32-bit integers set to edge values: NaN, ±Inf, 65504, 2³¹ ...), stored raw afterwards;
/// - the section list (a prefix of the sections, as a streamed package is, or one section
///   removed);
/// - raw bytes anywhere (libFuzzer's mutations of the whole file), then the checksums of
///   whatever layout that left recomputed.
///
/// The inputs it produces are valid as far as checksums go, so the normal build, which verifies
/// them, replays them exactly as the fuzzer ran them: no fuzzing-only code path in the library.
#include <cstddef>
#include <cstdint>

namespace btf::fuzz {

/// libFuzzer's LLVMFuzzerCustomMutator contract: mutates `data` (`size` bytes) in place into at
/// most `max_size` bytes and returns the new size.
size_t mutate_package(uint8_t* data, size_t size, size_t max_size, unsigned int seed);

}  // namespace btf::fuzz

/// Makes mutate_package() the target's mutator: put this in a target that reads packages.
#define BTF_FUZZ_PACKAGE_MUTATOR()                                                         \
    extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, \
                                              unsigned int seed) {                         \
        return btf::fuzz::mutate_package(data, size, max_size, seed);                      \
    }
