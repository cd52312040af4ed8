// SPDX-License-Identifier: MIT
#include "btf/util/limits.h"

#include <atomic>
#include <charconv>
#include <cstdlib>
#include <mutex>

#include "btf/util/error.h"

namespace btf {

namespace {

constexpr const char* kPixelsVariable = "BTF_MAX_IMAGE_PIXELS";
constexpr const char* kAllocVariable = "BTF_MAX_ALLOC";
constexpr const char* kExternalVariable = "BTF_ALLOW_HDF5_EXTERNAL";

std::optional<uint64_t> parse_count(std::string_view text) {
    uint64_t value = 0;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || ptr != text.data() + text.size() || value == 0) return std::nullopt;
    return value;
}

// A variable that is set must be valid: a typo must not silently leave the default in force.
Limits from_environment() {
    Limits l;
    if (const char* v = std::getenv(kPixelsVariable)) {
        const auto n = parse_count(v);
        if (!n || *n > uint64_t(INT64_MAX))
            fail("{}={}: expected a positive whole number of texels", kPixelsVariable, v);
        l.image_pixels = int64_t(*n);
    }
    if (const char* v = std::getenv(kAllocVariable)) {
        const auto n = parse_limit_bytes(v);
        if (!n) fail("{}={}: expected a positive byte count such as 8G or 512M", kAllocVariable, v);
        l.alloc_bytes = *n;
    }
    if (const char* v = std::getenv(kExternalVariable)) {
        const std::string_view text(v);
        if (text != "0" && text != "1") fail("{}={}: expected 0 or 1", kExternalVariable, v);
        l.allow_hdf5_external = text == "1";
    }
    return l;
}

// Read without a lock once set: a forked child (util/isolate.h) reads them, and a lock held by
// another thread of the parent at the fork would never be released there.
std::mutex g_set_mutex;  // serializes the first read of the environment and set_limits()
std::atomic<bool> g_ready{false};
std::atomic<int64_t> g_image_pixels{0};
std::atomic<uint64_t> g_alloc_bytes{0};
std::atomic<bool> g_allow_hdf5_external{false};

void store(const Limits& l) {
    g_image_pixels.store(l.image_pixels);
    g_alloc_bytes.store(l.alloc_bytes);
    g_allow_hdf5_external.store(l.allow_hdf5_external);
    g_ready.store(true);
}

}  // namespace

Limits limits() {
    if (!g_ready.load()) {
        std::lock_guard lock(g_set_mutex);
        if (!g_ready.load()) store(from_environment());
    }
    return {g_image_pixels.load(), g_alloc_bytes.load(), g_allow_hdf5_external.load()};
}

void set_limits(const Limits& l) {
    if (l.image_pixels <= 0 || l.alloc_bytes == 0) fail("limits must be positive");
    std::lock_guard lock(g_set_mutex);
    store(l);
}

void check_image_size(int64_t width, int64_t height, std::string_view what) {
    if (width <= 0 || height <= 0)
        fail("{}: image of {}×{} texels has no texels", what, width, height);
    const int64_t limit = limits().image_pixels;
    if (width > limit || height > limit / width)
        fail(
            "{}: image of {}×{} texels exceeds the limit of {} texels (raise it with "
            "--max-image-pixels or {})",
            what, width, height, limit, kPixelsVariable);
}

void check_alloc(uint64_t bytes, std::string_view what, std::string_view content) {
    const uint64_t limit = limits().alloc_bytes;
    if (bytes > limit)
        fail("{}: {} needs {} bytes, over the limit of {} (raise it with --max-alloc or {})", what,
             content, bytes, format_limit_bytes(limit), kAllocVariable);
}

std::optional<uint64_t> checked_bytes(uint64_t count, uint64_t size) {
    uint64_t out = 0;
    if (__builtin_mul_overflow(count, size, &out)) return std::nullopt;
    return out;
}

std::string format_limit_bytes(uint64_t bytes) {
    static constexpr const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    int unit = 0;
    while (unit < 6 && bytes >= 1024 && bytes % 1024 == 0) bytes /= 1024, ++unit;
    return fmt::format("{} {}", bytes, kUnits[unit]);
}

std::optional<uint64_t> parse_limit_bytes(std::string_view text) {
    int shift = 0;
    if (!text.empty()) {
        switch (text.back()) {
            case 'K':
            case 'k':
                shift = 10;
                break;
            case 'M':
            case 'm':
                shift = 20;
                break;
            case 'G':
            case 'g':
                shift = 30;
                break;
            case 'T':
            case 't':
                shift = 40;
                break;
            default:
                break;
        }
        if (shift) text.remove_suffix(1);
    }
    const auto n = parse_count(text);
    if (!n || *n > (UINT64_MAX >> shift)) return std::nullopt;
    return *n << shift;
}

}  // namespace btf
