// SPDX-License-Identifier: MIT
#pragma once
/// The sizes btfkit accepts from input before it allocates for them: one place for every limit
/// a reader or decoder applies to what a file declares (docs/formats.md, "Limits"). A crafted
/// header that claims a 65500² image, a 2³¹-entry code-book or a 1 GiB zip entry is refused with
/// a one-line error naming the file and the limit, instead of exhausting memory.
///
/// Each limit has a default, an environment variable that replaces it, and a `btf` option that
/// replaces both for one run:
///
///   limit          default            environment variable     btf option
///   image_pixels   67 108 864 (8192²) BTF_MAX_IMAGE_PIXELS     --max-image-pixels N
///   alloc_bytes    4 GiB              BTF_MAX_ALLOC            --max-alloc BYTES (K/M/G/T)
///   allow_hdf5_external  no           BTF_ALLOW_HDF5_EXTERNAL=1 --allow-hdf5-external

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace btf {

struct Limits {
    /// Largest image, width × height texels, that a reader decodes or a file may declare (a raw
    /// image, a package's or a DFMF file's extent).
    int64_t image_pixels = int64_t(1) << 26;
    /// Largest single block of memory allocated for what a file declares: a decoded section, a
    /// code-book, a factor matrix, an image file's bytes, a decoded image.
    uint64_t alloc_bytes = uint64_t(4) << 30;
    /// Whether an HDF5 file may reach other files: external links, external raw storage and
    /// virtual datasets are refused unless this is set (BTF_ALLOW_HDF5_EXTERNAL=1,
    /// --allow-hdf5-external).
    bool allow_hdf5_external = false;
};

/// The limits in force: the defaults, replaced by the environment variables on first use, and
/// by set_limits(). Thread-safe; after the first call it takes no lock (so a forked child may
/// call it).
Limits limits();
/// Replaces the limits for the whole process (the CLI's options). Throws btf::Error for a zero.
void set_limits(const Limits& limits);

/// Throws btf::Error "WHAT: image of W×H texels exceeds the limit of N texels (…how to raise
/// it)" unless 0 < width, 0 < height and width × height ≤ limits().image_pixels.
void check_image_size(int64_t width, int64_t height, std::string_view what);
/// Throws btf::Error "WHAT: CONTENT needs N bytes, over the limit of M bytes (…)" unless
/// `bytes` ≤ limits().alloc_bytes. `content` says what the bytes are for ("section 'P1'").
void check_alloc(uint64_t bytes, std::string_view what, std::string_view content);
/// count × size in bytes, or nothing when the product overflows 64 bits.
std::optional<uint64_t> checked_bytes(uint64_t count, uint64_t size);

/// "4 GiB", "64 MiB", "1000 B": a byte count as the limits are written (exact binary units
/// where they fit, plain bytes otherwise).
std::string format_limit_bytes(uint64_t bytes);
/// Parses "123", "64K", "512M", "4G", "1T" (binary multiples); nothing on bad text or zero.
std::optional<uint64_t> parse_limit_bytes(std::string_view text);

}  // namespace btf
