// SPDX-License-Identifier: MIT
#pragma once
/// Opening any BTF by path: the registry of readers. Adding a reader means adding its files under
/// io/ and one line to the registry in open.cpp.

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "btf/core/image.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf {

struct OpenOptions {
    /// How 8-bit images are decoded: sRGB → linear (default) or raw code values.
    Encoding encoding = Encoding::kLinear;
    /// Open only these views (indices into the format's full view set); empty = all present.
    std::vector<int> views;
};

struct Reader {
    std::string name;         ///< short name: "ubo2003", "ubo2014", "utia", "hdf5", "synth"
    std::string description;  ///< one line for `btf formats` / help texts
    /// True if `path` looks like this format (cheap: signature or file names, no full parse).
    std::function<bool(const std::filesystem::path&)> probe;
    std::function<std::unique_ptr<BtfSource>(const std::filesystem::path&, const OpenOptions&)>
        open;
};

/// Every compiled-in reader, in probing order.
const std::vector<Reader>& readers();

/// Opens `path` with the first reader whose probe accepts it. Throws btf::Error naming the path
/// if the path does not exist or no reader recognizes it.
std::unique_ptr<BtfSource> open_source(const std::filesystem::path& path,
                                       const OpenOptions& options = {});

/// How write_source() stores values.
struct RawWriteOptions {
    bool half = true;  ///< HDF5: IEEE half floats rather than float32
    int deflate = 0;   ///< HDF5: 0 = none, 1–9 = deflate level
    /// UTIA image sets: "png" or "exr"; empty = exr for HDR sources, png otherwise.
    std::string format;
};

/// Writes `source` raw: btfkit HDF5 when `output` ends in .h5 or .hdf5, otherwise a UTIA image set
/// in the new folder `output`. Nothing is left at `output` when it fails or is cancelled.
void write_source(const BtfSource& source, const std::filesystem::path& output,
                  const RawWriteOptions& options = {}, Progress& progress = Progress::none());

}  // namespace btf
