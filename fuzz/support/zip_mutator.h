// SPDX-License-Identifier: MIT
#pragma once
/// Structure-aware mutation of zip archives (the UBO2003 reader's input). libzip checks each
/// entry's CRC-32 as it reads it, so a byte-level mutation of an entry's data only reaches that
/// check. This mutator reads the archive with libzip, changes one entry (its name, with
/// libFuzzer's mutations or a digit of a number changed; its data; removed; added again under
/// another name) and writes a new archive, entries stored uncompressed with their CRCs
/// computed. One mutation in four is libFuzzer's byte-level one on the whole archive, for the
/// container itself.
#include <cstddef>
#include <cstdint>

namespace btf::fuzz {

/// libFuzzer's LLVMFuzzerCustomMutator contract.
size_t mutate_zip(uint8_t* data, size_t size, size_t max_size, unsigned int seed);

}  // namespace btf::fuzz

/// Makes mutate_zip() the target's mutator.
#define BTF_FUZZ_ZIP_MUTATOR()                                                             \
    extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, \
                                              unsigned int seed) {                         \
        return btf::fuzz::mutate_zip(data, size, max_size, seed);                          \
    }
