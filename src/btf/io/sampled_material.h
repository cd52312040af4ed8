// SPDX-License-Identifier: MIT
#pragma once
/// A Material over an uncompressed BTF: every (view, light) image of a source held in memory as
/// half floats and interpolated exactly like every codec's evaluator (btf::lookup6d: bilinear in
/// space × barycentric over the ≤ 3 nearest views × ≤ 3 nearest lights). This is how raw data
/// (UBO2003 archives, UTIA image sets, btfkit HDF5, synthetic materials) is rendered, e.g. as the
/// reference a compressed version is compared with.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "btf/core/angular_interpolator.h"
#include "btf/core/material.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf {

class SampledMaterial final : public Material {
  public:
    /// Reads every image of `source` (in parallel). Throws btf::Error naming the source when
    /// its samples would need more than `memory_limit` bytes (6 bytes per texel and image).
    SampledMaterial(const BtfSource& source, int64_t memory_limit = int64_t(4) << 30,
                    Progress& progress = Progress::none());

    int width() const override { return m_width; }
    int height() const override { return m_height; }
    const Sampling& sampling() const override { return m_sampling; }
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override;
    Rgb eval_sample(int x, int y, int view, int light) const override;

  private:
    int m_width, m_height;
    Sampling m_sampling;
    std::unique_ptr<AngularInterpolator> m_views, m_lights;
    std::vector<uint16_t> m_samples;  // half floats, [view][light][y][x][rgb]
};

/// Opens any BTF that a reader recognizes (btf/io/open.h) as a SampledMaterial.
std::unique_ptr<SampledMaterial> open_sampled_material(const std::filesystem::path& path,
                                                       Progress& progress = Progress::none());

}  // namespace btf
