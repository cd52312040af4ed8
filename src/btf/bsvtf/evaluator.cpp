// SPDX-License-Identifier: MIT
#include "btf/bsvtf/evaluator.h"

#include <algorithm>

#include "btf/util/error.h"

namespace btf::bsvtf {

Evaluator::Evaluator(const factor::Model& model, const TileLayout& layout)
    : m_model(&model),
      m_layout(&layout),
      m_views(std::make_unique<AngularInterpolator>(model.sampling.views)),
      m_lights(std::make_unique<AngularInterpolator>(model.sampling.lights)),
      m_channels(model.colour.channels()),
      m_planes(model.colour.planes()) {
    if (model.groups.size() != 1 || model.clusters != 1 || model.levels != 1)
        throw Error("bsvtf: the evaluator needs a single-block factorization (fmf)");
    m_slot.assign(size_t(model.sampling.num_views()), -1);
    for (size_t s = 0; s < model.groups[0].size(); ++s) m_slot[size_t(model.groups[0][s])] = int(s);
    for (int p = 0; p < m_planes; ++p) {
        m_components.push_back(model.blocks[size_t(model.block_index(p, 0, 0))].components());
        m_stride = std::max(m_stride, m_components.back());
    }
}

void Evaluator::angular(const Vec3& wi, const Vec3& wo, Angular& out) const {
    const AngularWeights vw = m_views->weights(wo), lw = m_lights->weights(wi);
    const int nl = m_model->sampling.num_lights();
    out.a.assign(size_t(m_planes * m_channels * m_stride), 0.0f);
    out.mean.fill(0.0f);
    for (int p = 0; p < m_planes; ++p) {
        const factor::Block& block = m_model->blocks[size_t(m_model->block_index(p, 0, 0))];
        const int k = m_components[size_t(p)];
        for (int v = 0; v < vw.count; ++v) {
            if (vw.weight[size_t(v)] == 0) continue;
            const int slot = m_slot[size_t(vw.index[size_t(v)])];
            for (int l = 0; l < lw.count; ++l) {
                const float w = vw.weight[size_t(v)] * lw.weight[size_t(l)];
                if (w == 0) continue;
                for (int ch = 0; ch < m_channels; ++ch) {
                    const int64_t row =
                        (int64_t(slot) * nl + lw.index[size_t(l)]) * m_channels + ch;
                    float* acc = out.a.data() + size_t((p * m_channels + ch) * m_stride);
                    for (int c = 0; c < k; ++c) acc[c] += w * block.a(row, c);
                    if (!block.mean.empty())
                        out.mean[size_t(p * 3 + ch)] += w * block.mean[size_t(row)];
                }
            }
        }
    }
}

}  // namespace btf::bsvtf
