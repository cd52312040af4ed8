// SPDX-License-Identifier: MIT
#pragma once
/// The interface between btfkit and its image module, libbtfkit_images.so: the only code that
/// links OpenImageIO, loaded with dlopen the first time an image file is read or written.
///
/// Debian's OpenImageIO pulls about 250 shared libraries into a process (OpenCV, FFmpeg,
/// GStreamer, OpenVDB, OpenBLAS, ...) whose relocation and static constructors took 0.44 s of
/// every process start: `btf info` on a package, each test program and each `btf` a test runs
/// paid it whether or not it touched an image. Loaded on demand, only a process that decodes or
/// writes a picture pays it, and pays it once.
///
/// Both sides are built from this tree by the same compiler, so the table passes C++ types; no
/// exception crosses it (every failure comes back as `false` or null and a message).

#include <cstddef>
#include <cstdint>
#include <string>

namespace btf::image_module {

/// Bumped whenever the table changes; a module built with another version is refused.
inline constexpr uint32_t kAbiVersion = 2;

/// What an opened image declares in its header.
struct Header {
    int width = 0, height = 0, channels = 0;
    int depth = 1;          ///< slices of a volume image (DDS, TIFF): read() would decode them all
    bool is_float = false;  ///< float, half or double samples (taken as linear)
    bool is_8bit = false;   ///< 8-bit unsigned samples
};

/// How write() stores the samples.
enum class Sample : int { kUint8, kHalf, kFloat };

/// An image being read; opaque to btfkit.
struct Reader;

/// Called between scanlines; returning true abandons the decode.
using CancelCheck = bool (*)();

struct Table {
    uint32_t abi_version;
    /// Opens `name` from the file of that name (`data` null) or from `size` bytes at `data`
    /// (the format is chosen by the bytes and the extension of `name`). `limit_mb` is the
    /// decoders' own bound on a header's size. Null on failure, with the reason in `error`.
    Reader* (*open)(const std::string& name, const void* data, size_t size, int limit_mb,
                    std::string* error);
    Header (*header)(const Reader* reader);
    /// Decodes every channel into `pixels` (width × height × depth × channels values of 8-bit or
    /// float samples); false with the decoder's first error line when it fails or reports damage.
    bool (*read)(Reader* reader, bool as_8bit, void* pixels, CancelCheck cancelled,
                 std::string* error);
    void (*close)(Reader* reader);
    /// True if `name`'s extension names a format the module can write.
    bool (*can_write)(const std::string& name);
    /// Writes `pixels` (width × height × channels floats) to `temp_path` in the format that
    /// `name`'s extension names, with `compression` ("" for the default) and colour space.
    bool (*write)(const std::string& name, const std::string& temp_path, int width, int height,
                  int channels, const float* pixels, Sample sample, const std::string& compression,
                  const std::string& colour_space, std::string* error);
};

}  // namespace btf::image_module

/// The module's one exported symbol.
extern "C" const btf::image_module::Table* btf_image_module_table();
