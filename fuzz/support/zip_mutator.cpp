// SPDX-License-Identifier: MIT
#include "fuzz/support/zip_mutator.h"

#include <zip.h>

#include <cstdlib>
#include <cstring>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

namespace btf::fuzz {

namespace {

using Rng = std::mt19937_64;

// Archives whose entries inflate to more than this are mutated as bytes only.
constexpr uint64_t kMaxContent = uint64_t(32) << 20;

struct Entry {
    std::string name;
    std::vector<uint8_t> data;
};

std::optional<std::vector<Entry>> read_entries(const uint8_t* data, size_t size) {
    zip_error_t error;
    zip_error_init(&error);
    zip_source_t* source = zip_source_buffer_create(data, size, 0, &error);
    if (!source) return std::nullopt;
    zip_t* archive = zip_open_from_source(source, ZIP_RDONLY, &error);
    zip_error_fini(&error);
    if (!archive) {
        zip_source_free(source);
        return std::nullopt;
    }
    std::vector<Entry> entries;
    uint64_t total = 0;
    bool ok = true;
    const zip_int64_t n = zip_get_num_entries(archive, 0);
    for (zip_int64_t i = 0; ok && i < n; ++i) {
        zip_stat_t st;
        if (zip_stat_index(archive, zip_uint64_t(i), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE) ||
            !(st.valid & ZIP_STAT_NAME) || (total += st.size) > kMaxContent) {
            ok = false;
            break;
        }
        Entry e{st.name, std::vector<uint8_t>(st.size)};
        zip_file_t* file = zip_fopen_index(archive, zip_uint64_t(i), 0);
        if (!file) {
            ok = false;
            break;
        }
        ok = zip_fread(file, e.data.data(), e.data.size()) == zip_int64_t(e.data.size());
        zip_fclose(file);
        entries.push_back(std::move(e));
    }
    zip_discard(archive);
    if (!ok) return std::nullopt;
    return entries;
}

std::optional<std::vector<uint8_t>> write_entries(const std::vector<Entry>& entries) {
    zip_error_t error;
    zip_error_init(&error);
    zip_source_t* source = zip_source_buffer_create(nullptr, 0, 0, &error);
    zip_error_fini(&error);
    if (!source) return std::nullopt;
    zip_source_keep(source);
    zip_error_init(&error);
    zip_t* archive = zip_open_from_source(source, ZIP_TRUNCATE, &error);
    zip_error_fini(&error);
    if (!archive) {
        zip_source_free(source);
        return std::nullopt;
    }
    for (const Entry& e : entries) {
        void* copy = std::malloc(e.data.empty() ? 1 : e.data.size());
        if (!e.data.empty()) std::memcpy(copy, e.data.data(), e.data.size());
        zip_source_t* s = zip_source_buffer(archive, copy, e.data.size(), 1);
        if (!s) {
            std::free(copy);
            continue;
        }
        const zip_int64_t index = zip_file_add(archive, e.name.c_str(), s, ZIP_FL_ENC_UTF_8);
        if (index < 0) {
            zip_source_free(s);  // a name libzip refuses (e.g. a duplicate): left out
            continue;
        }
        zip_set_file_compression(archive, zip_uint64_t(index), ZIP_CM_STORE, 0);
    }
    if (zip_close(archive) != 0) {
        zip_discard(archive);
        zip_source_free(source);
        return std::nullopt;
    }
    std::optional<std::vector<uint8_t>> out;
    zip_stat_t st;
    if (zip_source_stat(source, &st) == 0 && (st.valid & ZIP_STAT_SIZE) &&
        zip_source_open(source) == 0) {
        std::vector<uint8_t> bytes(st.size);
        if (zip_source_read(source, bytes.data(), bytes.size()) == zip_int64_t(bytes.size()))
            out = std::move(bytes);
        zip_source_close(source);
    }
    zip_source_free(source);
    return out;
}

void mutate_name(std::string& name, Rng& rng) {
    if (rng() % 2 == 0) {
        // A digit changed: another angle or running number that still parses.
        std::vector<size_t> digits;
        for (size_t i = 0; i < name.size(); ++i)
            if (name[i] >= '0' && name[i] <= '9') digits.push_back(i);
        if (!digits.empty()) {
            name[digits[rng() % digits.size()]] = char('0' + rng() % 10);
            return;
        }
    }
    const size_t max = name.size() * 2 + 16;
    const size_t old = name.size();
    name.resize(max);
    name.resize(LLVMFuzzerMutate(reinterpret_cast<uint8_t*>(name.data()), old, max));
}

}  // namespace

size_t mutate_zip(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
    Rng rng(seed);
    std::optional<std::vector<Entry>> entries;
    if (rng() % 4 != 0) entries = read_entries(data, size);
    if (!entries || entries->empty()) return LLVMFuzzerMutate(data, size, max_size);
    std::vector<Entry>& e = *entries;
    Entry& pick = e[rng() % e.size()];
    switch (rng() % 5) {
        case 0:
        case 1:
            mutate_name(pick.name, rng);
            break;
        case 2: {
            const size_t old = pick.data.size();
            const size_t max = old * 2 + 64;
            pick.data.resize(max);
            pick.data.resize(LLVMFuzzerMutate(pick.data.data(), old, max));
            break;
        }
        case 3:
            e.erase(e.begin() + (&pick - e.data()));
            break;
        default: {
            Entry copy = pick;
            mutate_name(copy.name, rng);
            e.push_back(std::move(copy));
            break;
        }
    }
    std::optional<std::vector<uint8_t>> out = write_entries(e);
    if (!out || out->size() > max_size) return LLVMFuzzerMutate(data, size, max_size);
    std::memcpy(data, out->data(), out->size());
    return out->size();
}

}  // namespace btf::fuzz
