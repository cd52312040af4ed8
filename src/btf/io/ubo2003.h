// SPDX-License-Identifier: MIT
#pragma once
/// Reader for Bonn UBO2003 materials (the "BTFDBB" database of 2003), layout "MANYFILES":
///
///     [top folder/]tvTTT_pvPPP/NNNNN tlTTT plPPP tvTTT pvPPP.jpg
///
/// one folder per view, one image per light, angles in whole degrees, NNNNN = 81 · light index +
/// view index (indices into DirectionSet::ubo81()). The material is a zip archive read in place
/// or the extracted tree; the path may also name the top folder or a single view folder. The
/// ATRIUM HDR sibling (same names, `.hdr` float images) is read the same way.
///
/// Angles come from the file names only (never from directory or archive order). The source's
/// views are the present (or chosen) views in ubo81 order; its lights are all 81 of ubo81, and
/// every view must have all of them. Names, counts, the archive's directory and every image
/// header are checked when opening; pixels are decoded in read_image (thread-safe). JPEGs are
/// sRGB-decoded to linear unless OpenOptions::encoding is Encoding::kRaw.

#include <filesystem>
#include <memory>
#include <vector>

#include "btf/io/open.h"
#include "btf/io/source.h"

namespace btf::ubo2003 {

/// True if `path` is a zip archive, or a folder (a material, its top folder or one view folder),
/// that holds UBO2003 image names. Looks at names only. A file named *.zip that is not a readable
/// archive is claimed too, so that open() reports what is wrong with it.
bool probe(const std::filesystem::path& path);

/// Opens a UBO2003 material. `options.views` picks views by their index in ubo81 (empty = every
/// view that has images). Throws btf::Error with a one-line message naming the archive or file
/// and the problem: unparsable image name, angle not in ubo81, running number that does not
/// match the angles, duplicate image, missing light image, images of different sizes, a corrupt
/// or truncated archive, a file that is not an image.
std::unique_ptr<BtfSource> open(const std::filesystem::path& path, const OpenOptions& options = {});

/// Indices into DirectionSet::ubo81() of the views that have at least one image in the material,
/// ascending. Checks the image names (as open() does) but not that each view is complete.
std::vector<int> list_views(const std::filesystem::path& path);

}  // namespace btf::ubo2003
