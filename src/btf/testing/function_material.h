// SPDX-License-Identifier: MIT
#pragma once
// Analytic materials for tests (GoogleTest only; not part of the library): a Material whose value
// is a function of (uv, ωi, ωo), and the Lambertian material value = ρ · cos θi.

#include <algorithm>
#include <functional>
#include <utility>

#include "btf/core/direction.h"
#include "btf/core/material.h"

namespace btf::test {

/// value = fn(uv, wi, wo) exactly (no interpolation); eval_sample() evaluates fn at the texel's
/// centre and the sampled directions. `fn` must be thread-safe.
class FunctionMaterial final : public Material {
  public:
    using Fn = std::function<Rgb(const Uv& uv, const Vec3& wi, const Vec3& wo)>;

    FunctionMaterial(int width, int height, Sampling sampling, Fn fn)
        : m_width(width), m_height(height), m_sampling(std::move(sampling)), m_fn(std::move(fn)) {}

    int width() const override { return m_width; }
    int height() const override { return m_height; }
    const Sampling& sampling() const override { return m_sampling; }
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override {
        return m_fn(uv, wi, wo);
    }
    Rgb eval_sample(int x, int y, int view, int light) const override {
        return m_fn({(x + 0.5) / m_width, (y + 0.5) / m_height}, m_sampling.lights.vector(light),
                    m_sampling.views.vector(view));
    }

  protected:
    /// An analytic material has no terms to draw: a stochastic vertex's value is the function
    /// itself (its sampling still uses the selected texel's and view's generic table).
    Rgb eval_selected(const Selection&, const Uv& uv, const Vec3& wo,
                      const Vec3& wi) const override {
        return m_fn(uv, wi, wo);
    }

  private:
    int m_width, m_height;
    Sampling m_sampling;
    Fn m_fn;
};

/// A Lambertian surface of albedo ρ (per channel) at every texel: value = ρ · max(cos θi, 0),
/// size × size texels, sampled at the UBO2003 directions.
inline FunctionMaterial lambertian_material(const Rgb& rho, int size = 8) {
    const DirectionSet& ubo = DirectionSet::ubo81();
    return FunctionMaterial(size, size, {ubo, ubo}, [rho](const Uv&, const Vec3& wi, const Vec3&) {
        return rho * static_cast<float>(std::max(wi.z, 0.0));
    });
}

}  // namespace btf::test
