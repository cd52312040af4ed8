// SPDX-License-Identifier: MIT
#pragma once
/// UTIA image sets: one folder, one image per (light, view), named
///
///     tlTTT_plPPP_tvTTT_pvPPP.png   (8-bit sRGB)      or      ….exr   (half float, CIE XYZ)
///
/// Angles are in degrees: three digits for whole degrees ("tl075"), or for angles between whole
/// degrees three integer digits, '.', and up to three decimals ("tl023.5", "pl007.25"); φ is
/// written 000 at θ = 0. The sampling is deduced from the names: each of the light and view sets
/// is DirectionSet::ubo81() (or dome151()) when its angles are exactly that set, else the distinct
/// directions found ordered by θ, then φ. Every (view, light) pair must be present. EXR values
/// are CIE XYZ (D65, Y = 1 for white) and are converted to linear RGB with core/color.h.

#include <filesystem>
#include <memory>
#include <string>

#include "btf/io/open.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf::utia {

/// True if `path` is a folder holding at least one file named like a UTIA image
/// (tlTTT_plPPP_tvTTT_pvPPP.png or .exr). Looks at names only.
bool probe(const std::filesystem::path& path);

/// Opens a UTIA image set folder. `options.views` picks views by index into the deduced view set
/// (empty = all); `options.encoding` applies to PNG files. Throws btf::Error naming the folder or
/// file and the problem (unparsable name, duplicate or missing image, mixed formats or sizes,
/// unreadable image).
std::unique_ptr<BtfSource> open(const std::filesystem::path& path, const OpenOptions& options = {});

/// Writes `source` as a new UTIA image set folder `folder`, format "png" (8-bit sRGB) or "exr"
/// (half float, CIE XYZ). The folder is written under a temporary name and renamed into place
/// when complete; an existing folder (or file) at `folder` is refused. Names follow
/// file_name(); two directions that give the same name are an error.
void write(const BtfSource& source, const std::filesystem::path& folder, const std::string& format,
           Progress& progress = Progress::none());

/// The file name the writer uses for a (light, view) pair, e.g. "tl045_pl020_tv000_pv000.png".
/// `format` is "png" or "exr".
std::string file_name(const Direction& light, const Direction& view, const std::string& format);

}  // namespace btf::utia

namespace btf {

/// Same as utia::write.
inline void write_utia(const BtfSource& source, const std::filesystem::path& folder,
                       const std::string& format, Progress& progress = Progress::none()) {
    utia::write(source, folder, format, progress);
}

}  // namespace btf
