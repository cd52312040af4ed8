// SPDX-License-Identifier: MIT
#pragma once
// Test support (GoogleTest only; not part of the library): a fresh folder per test, the
// message of an expected btf::Error, and whole files read and written as strings.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "btf/util/error.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

// 1 in a build with AddressSanitizer (GCC says so by __SANITIZE_ADDRESS__, clang before 17 only
// through __has_feature): tests that cap a process's memory skip themselves there, since ASan's
// shadow memory and allocator do not work under such caps.
#if defined(__SANITIZE_ADDRESS__)
#define BTF_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define BTF_TEST_ASAN 1
#endif
#endif
#ifndef BTF_TEST_ASAN
#define BTF_TEST_ASAN 0
#endif

namespace btf::test {

/// A new empty folder under GoogleTest's temporary folder, removed with everything in it when
/// the object goes. Unique per process, test and object: CTest runs test processes in parallel.
class TempFolder {
  public:
    explicit TempFolder(const std::string& prefix = "btf") {
        static std::atomic<int> counter{0};
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        m_path = std::filesystem::path(::testing::TempDir()) /
                 (prefix + "_" + (info ? info->name() : "suite") + "_" +
                  std::to_string(::getpid()) + "_" + std::to_string(counter++));
        std::filesystem::remove_all(m_path);
        std::filesystem::create_directories(m_path);
    }
    ~TempFolder() {
        std::error_code ec;
        std::filesystem::remove_all(m_path, ec);
    }
    TempFolder(const TempFolder&) = delete;
    TempFolder& operator=(const TempFolder&) = delete;

    const std::filesystem::path& path() const { return m_path; }

  private:
    std::filesystem::path m_path;
};

/// Runs `fn`, which must throw btf::Error, and returns the error's message (records a test
/// failure and returns "" if it does not throw).
template <typename Fn>
std::string error_of(Fn&& fn) {
    try {
        fn();
    } catch (const Error& e) {
        return e.what();
    }
    ADD_FAILURE() << "expected a btf::Error";
    return {};
}

/// The process's limits (util/limits.h) changed for one scope: `edit` changes a copy of those in
/// force, and the old ones come back when the scope ends, also when a failed check throws.
class ScopedLimits {
  public:
    template <typename Edit>
    explicit ScopedLimits(Edit&& edit) : m_saved(limits()) {
        Limits changed = m_saved;
        edit(changed);
        set_limits(changed);
    }
    ~ScopedLimits() { set_limits(m_saved); }
    ScopedLimits(const ScopedLimits&) = delete;
    ScopedLimits& operator=(const ScopedLimits&) = delete;

  private:
    Limits m_saved;
};

/// The bytes of a file ("" when it cannot be read).
/// What `make` returns (bytes) with 1, 2 and all worker threads: for checks that results do not
/// depend on the thread count.
template <typename Fn>
std::vector<std::vector<uint8_t>> bytes_per_thread_count(Fn&& make) {
    std::vector<std::vector<uint8_t>> out;
    for (int threads : {1, 2, 0}) {
        const ThreadLimit limit(threads);
        out.push_back(make());
    }
    return out;
}

inline std::string read_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Writes `bytes` to a file, replacing it.
inline void write_file(const std::filesystem::path& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary) << bytes;
}

}  // namespace btf::test
