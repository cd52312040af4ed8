// SPDX-License-Identifier: MIT
// A UBO2014 factorization as a Material that interpolates decoded RGB samples: the one
// AngularInterpolator for views and lights and lookup6d's bilinear × barycentric weighting, over
// samples decoded to linear RGB one by one (cosine flag divided out). Only files with the cosine
// flag are opened this way (ubo2014.h, make_material); the others become the fmf evaluator of
// their factors (codecs/dfmf_export.h).

#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"
#include "btf/io/ubo2014.h"
#include "btf/util/error.h"

namespace btf::ubo2014 {

namespace {

class FactorizationMaterial final : public Material {
  public:
    explicit FactorizationMaterial(std::shared_ptr<const Factorization> f)
        : m_f((f->validate("UBO2014 factorization"), std::move(f))),
          m_views(m_f->sampling.views),
          m_lights(m_f->sampling.lights) {}

    int width() const override { return m_f->width; }
    int height() const override { return m_f->height; }
    const Sampling& sampling() const override { return m_f->sampling; }

    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override {
        const AngularWeights views = m_views.weights(wo);
        const AngularWeights lights = m_lights.weights(wi);
        return lookup6d(
            uv, m_f->width, m_f->height, views, lights,
            [this](int x, int y, int view, int light) { return m_f->sample(x, y, view, light); });
    }

    Rgb eval_sample(int x, int y, int view, int light) const override {
        return m_f->sample(x, y, view, light);
    }

  private:
    std::shared_ptr<const Factorization> m_f;
    AngularInterpolator m_views;
    AngularInterpolator m_lights;
};

}  // namespace

std::unique_ptr<Material> make_material(std::shared_ptr<const Factorization> factorization) {
    return std::make_unique<FactorizationMaterial>(std::move(factorization));
}

}  // namespace btf::ubo2014
