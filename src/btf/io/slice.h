// SPDX-License-Identifier: MIT
#pragma once
/// Pictures of a BTF: the image at arbitrary light and view directions (through the shared
/// AngularInterpolator) and the apparent BRDF of one texel.

#include "btf/core/image.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf {

/// The image for light direction `wi` and view direction `wo` (unit vectors, local frame):
/// the ≤3 × ≤3 nearest sample images blended with barycentric weights. Reads at most 9 images.
Image slice_image(const BtfSource& source, const Vec3& wi, const Vec3& wo);

/// The apparent BRDF of texel (x, y): an image with one row per view and one column per light
/// (in the sampling's order), each cell `scale` × `scale` pixels. Reads every image once.
Image abrdf_image(const BtfSource& source, int x, int y, int scale = 1,
                  Progress& progress = Progress::none());

}  // namespace btf
