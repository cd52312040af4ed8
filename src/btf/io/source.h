// SPDX-License-Identifier: MIT
#pragma once
/// BtfSource: a read-only raw BTF, read image by image. Every reader (UBO2003, UBO2014 at its
/// sample directions, UTIA image sets, btfkit HDF5, the synthesizer) implements it, and every
/// consumer (codecs, metrics, converters) reads through it. A source never requires the whole
/// BTF in memory.

#include <cstdint>
#include <filesystem>
#include <string>

#include "btf/core/direction.h"
#include "btf/core/image.h"

namespace btf {

/// What a source's values are.
struct SourceInfo {
    std::string format;          ///< e.g. "UBO2003", "UBO2014 DFMF", "btfkit HDF5", "synthetic"
    std::filesystem::path path;  ///< file or folder it was read from; empty for synthetic data
    bool hdr = false;            ///< values may exceed 1 (HDR capture) rather than 8-bit LDR
    std::string note;  ///< free text shown by `btf info` (e.g. colour model, partial views)
};

class BtfSource {
  public:
    virtual ~BtfSource() = default;

    /// Texels per image row and per column.
    virtual int width() const = 0;
    virtual int height() const = 0;
    /// Views and lights; view v and light l index into these sets.
    virtual const Sampling& sampling() const = 0;
    virtual const SourceInfo& info() const = 0;

    /// Reads the image for view `view` and light `light` as linear RGB (3 channels, width ×
    /// height). Reuses `out`'s storage when its shape matches. Safe to call from several threads
    /// at once. Throws btf::Error naming the file and image on failure.
    virtual void read_image(int view, int light, Image& out) const = 0;

    /// Convenience: read_image into a new Image.
    Image image(int view, int light) const {
        Image out;
        read_image(view, light, out);
        return out;
    }
    int num_views() const { return sampling().num_views(); }
    int num_lights() const { return sampling().num_lights(); }
    int64_t num_texels() const { return int64_t(width()) * height(); }
    /// Size of the raw BTF as float32 RGB.
    int64_t raw_bytes() const { return num_texels() * 3 * 4 * sampling().num_images(); }
};

}  // namespace btf
