// SPDX-License-Identifier: MIT
#pragma once
/// Evaluating a BSVTF material: the factorized BTF value(row, texel) = mean[row] + Σ_k a(row, k) ·
/// b(texel, k) with the angular factors a interpolated exactly like FactorMaterial (≤ 3 views ×
/// ≤ 3 lights, barycentric) and the eigen-textures b read from tiles: per component group, the
/// four channels of a bilinear lookup in whichever tile the cache shows for the texel, at that
/// tile's level. With the finest tiles of every group it is FactorMaterial::eval (up to the order
/// of float additions).

#include <array>
#include <memory>
#include <optional>
#include <vector>

#include "btf/bsvtf/pyramid.h"
#include "btf/codecs/factor/model.h"
#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"

namespace btf::bsvtf {

class Evaluator {
  public:
    /// `model`: an fmf model whose blocks hold a (b may be empty); `layout`: its tiles.
    Evaluator(const factor::Model& model, const TileLayout& layout);

    /// The angular factors of one (wi, wo), accumulated over the interpolation's direction
    /// pairs: for each plane and channel, Σ w · a(row, k) for every component k, and the mean.
    struct Angular {
        std::vector<float> a;         // [plane][channel][component] (stride: components)
        std::array<float, 9> mean{};  // [plane][channel]
    };
    void angular(const Vec3& wi, const Vec3& wo, Angular& out) const;

    /// The value at texture position `uv` given the angular part: `sample(group, u, v)` returns
    /// the group's four channels there, or nothing when the group is not available (its
    /// components then contribute nothing).
    template <typename Sample>
    Rgb value(const Angular& angular, Sample&& sample) const;

    const TileLayout& layout() const { return *m_layout; }
    const factor::Model& model() const { return *m_model; }
    int components(int plane) const { return m_components[size_t(plane)]; }

  private:
    const factor::Model* m_model;
    const TileLayout* m_layout;
    std::unique_ptr<AngularInterpolator> m_views, m_lights;
    std::vector<int> m_slot;  // view index → position in the model's view group
    std::vector<int> m_components;
    int m_stride = 0;  // max components over planes
    int m_channels = 0, m_planes = 0;
};

template <typename Sample>
Rgb Evaluator::value(const Angular& angular, Sample&& sample) const {
    float planes[3] = {0, 0, 0};
    for (int p = 0; p < m_planes; ++p)
        for (int ch = 0; ch < m_channels; ++ch)
            planes[p * m_channels + ch] = angular.mean[size_t(p * 3 + ch)];
    const std::vector<Group>& groups = m_layout->groups();
    for (int g = 0; g < int(groups.size()); ++g) {
        const std::optional<std::array<float, 4>> b = sample(g);
        if (!b) continue;
        const Group& group = groups[size_t(g)];
        for (int ch = 0; ch < m_channels; ++ch) {
            const float* a =
                angular.a.data() + size_t((group.plane * m_channels + ch) * m_stride + group.first);
            float sum = 0;
            for (int c = 0; c < group.count; ++c) sum += a[c] * (*b)[size_t(c)];
            planes[group.plane * m_channels + ch] += sum;
        }
    }
    return m_model->colour.inverse(Rgb{planes[0], planes[1], planes[2]});
}

}  // namespace btf::bsvtf
