// SPDX-License-Identifier: MIT
#pragma once
/// Float images (interleaved channels, row-major, row 0 first) and their file I/O through
/// OpenImageIO. 8-bit files are sRGB-encoded; EXR/HDR hold linear values.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "btf/core/math.h"

namespace btf {

class Image {
  public:
    Image() = default;
    Image(int width, int height, int channels = 3, float fill = 0.0f);

    int width() const { return m_width; }
    int height() const { return m_height; }
    int channels() const { return m_channels; }
    int64_t num_pixels() const { return int64_t(m_width) * m_height; }
    bool empty() const { return m_data.empty(); }

    float* data() { return m_data.data(); }
    const float* data() const { return m_data.data(); }
    std::vector<float>& values() { return m_data; }
    const std::vector<float>& values() const { return m_data; }

    float& at(int x, int y, int c) { return m_data[(int64_t(y) * m_width + x) * m_channels + c]; }
    float at(int x, int y, int c) const {
        return m_data[(int64_t(y) * m_width + x) * m_channels + c];
    }
    Rgb rgb(int x, int y) const {
        const float* p = &m_data[(int64_t(y) * m_width + x) * m_channels];
        return {p[0], p[1], p[2]};
    }
    void set_rgb(int x, int y, const Rgb& v) {
        float* p = &m_data[(int64_t(y) * m_width + x) * m_channels];
        p[0] = v.r, p[1] = v.g, p[2] = v.b;
    }
    /// Bilinear lookup at continuous texel coordinates (texel centres at integer + 0.5), clamped
    /// to the edge; first three channels.
    Rgb bilinear(double x, double y) const;

    /// Resizes (contents undefined) only if the shape changes.
    void reshape(int width, int height, int channels);

  private:
    int m_width = 0, m_height = 0, m_channels = 0;
    std::vector<float> m_data;
};

/// How 8-bit image files map to floats.
enum class Encoding {
    kLinear,  ///< decode sRGB to linear reflectance (default for LDR inputs)
    kRaw,     ///< keep the stored code values, scaled to [0, 1]
};

/// Reads any image OpenImageIO understands (first three channels; grey is replicated).
/// 8/16-bit integer files are decoded per `encoding`; float files are taken as linear.
/// Throws btf::Error naming the file on failure.
Image read_image(const std::filesystem::path& path, Encoding encoding = Encoding::kLinear);
/// Reads an image held in memory (e.g. a JPEG inside a zip archive); `name` is used in errors.
Image read_image_memory(const void* data, size_t size, const std::string& name,
                        Encoding encoding = Encoding::kLinear);
/// Width and height from an image header held in memory (the format is chosen by the extension of
/// `name`); `data` may be just the start of the file. Returns nothing if the header cannot be
/// parsed from these bytes, with OpenImageIO's reason in `error` when given. Throws btf::Error
/// naming `name` for a header that declares no texels or more than limits().image_pixels.
std::optional<std::pair<int, int>> read_image_size_memory(const void* data, size_t size,
                                                          const std::string& name,
                                                          std::string* error = nullptr);
/// True for the extensions write_image() stores as linear floats (exr, hdr, tif, tiff, pfm);
/// other formats are 8-bit sRGB.
bool is_float_image_format(const std::filesystem::path& path);
/// The image module (OpenImageIO, core/image_module.h) this process reads and writes pictures
/// with: the path it was loaded from (loading it if it was not yet). Throws btf::Error when it
/// cannot be loaded, saying where it was looked for.
std::string image_module_path();
/// Looks for the image module at `path` first (before the places image.cpp knows), for a binary
/// that knows where its install puts it (the Python module). Call before the first image is read.
void add_image_module_candidate(const std::filesystem::path& path);
/// Throws btf::Error naming `path` unless write_image() can write its format and its folder
/// exists: the check a long computation makes before it starts.
void check_image_output(const std::filesystem::path& path);

/// Writes an image; format from the extension. 8-bit formats (png, jpg) are sRGB-encoded from
/// linear unless `encoding` is kRaw; exr is written as half floats, linear. Atomic (temp + rename).
void write_image(const std::filesystem::path& path, const Image& image,
                 Encoding encoding = Encoding::kLinear);

}  // namespace btf
