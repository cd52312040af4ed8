// SPDX-License-Identifier: MIT
#include "btf/core/material.h"

#include <cmath>

#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"
#include "btf/core/light_sampler.h"
#include "btf/util/error.h"

namespace btf {

namespace detail {

LazyLightSampler& LazyLightSampler::operator=(const LazyLightSampler&) {
    // The assigned material has new contents: a sampler built for the old ones would be stale.
    delete m_sampler.exchange(nullptr, std::memory_order_acq_rel);
    return *this;
}

LazyLightSampler::~LazyLightSampler() {
    delete m_sampler.load(std::memory_order_acquire);
}

const LightSampler& LazyLightSampler::get(const Material& material) const {
    if (const LightSampler* s = m_sampler.load(std::memory_order_acquire)) return *s;
    std::lock_guard lock(m_mutex);
    const LightSampler* s = m_sampler.load(std::memory_order_relaxed);
    if (!s) {
        s = new LightSampler(material);
        m_sampler.store(s, std::memory_order_release);
    }
    return *s;
}

struct Interpolators {
    AngularInterpolator views, lights;
    explicit Interpolators(const Sampling& s) : views(s.views), lights(s.lights) {}
};

LazyInterpolators& LazyInterpolators::operator=(const LazyInterpolators&) {
    delete m_value.exchange(nullptr, std::memory_order_acq_rel);
    return *this;
}

LazyInterpolators::~LazyInterpolators() {
    delete m_value.load(std::memory_order_acquire);
}

const Interpolators& LazyInterpolators::get(const Material& material) const {
    if (const Interpolators* p = m_value.load(std::memory_order_acquire)) return *p;
    std::lock_guard lock(m_mutex);
    const Interpolators* p = m_value.load(std::memory_order_relaxed);
    if (!p) {
        p = new Interpolators(material.sampling());
        m_value.store(p, std::memory_order_release);
    }
    return *p;
}

}  // namespace detail

const char* to_string(Filter filter) {
    return filter == Filter::kStochastic ? "stochastic" : "deterministic";
}

Filter parse_filter(const std::string& text, const std::string& what) {
    if (text == "deterministic") return Filter::kDeterministic;
    if (text == "stochastic") return Filter::kStochastic;
    fail("{}: '{}' is not a filter (deterministic or stochastic)", what, text);
}

LightSample Material::sample(const Uv& uv, const Vec3& wo, double xi1, double xi2) const {
    return generic_sampler().sample(uv, wo, xi1, xi2);
}

void Material::sample_batch(std::span<const SampleQuery> queries,
                            std::span<LightSample> out) const {
    if (queries.size() != out.size())
        fail("sample_batch: {} queries but {} outputs", queries.size(), out.size());
    for (size_t i = 0; i < queries.size(); ++i)
        out[i] = sample(queries[i].uv, queries[i].wo, queries[i].xi1, queries[i].xi2);
}

void Material::eval_sample_batch(std::span<const SampleIndex> indices, std::span<Rgb> out) const {
    if (indices.size() != out.size())
        fail("eval_sample_batch: {} indices but {} outputs", indices.size(), out.size());
    for (size_t i = 0; i < indices.size(); ++i)
        out[i] = eval_sample(indices[i].x, indices[i].y, indices[i].view, indices[i].light);
}

double Material::pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const {
    return generic_sampler().pdf(uv, wo, wi);
}

Rgb Material::albedo(const Uv& uv, const Vec3& wo) const {
    return quadrature_albedo(*this, uv, wo);
}

}  // namespace btf

namespace btf {

const AngularInterpolator& Material::view_interpolator() const {
    return m_interpolators.get(*this).views;
}

const AngularInterpolator& Material::light_interpolator() const {
    return m_interpolators.get(*this).lights;
}

Selection Material::select(const Uv& uv, const Vec3& wo, double u) const {
    const WrapLerp lx = wrap_lerp(uv.u, width()), ly = wrap_lerp(uv.v, height());
    Selection s;
    s.u = u;
    // The view first: its weights hardly change between the samples of a pixel, so a renderer's
    // stratified numbers (render::primary_filter_numbers()) stratify its draw; the texel's weights
    // change with every sample's position.
    const AngularWeights views = view_interpolator().weights(wo);
    s.view = views.index[size_t(pick<3>(views.weight.data(), views.count, s.u))];
    const float wx[2] = {1 - lx.t, lx.t}, wy[2] = {1 - ly.t, ly.t};
    s.x = pick<2>(wx, 2, s.u) == 0 ? lx.i0 : lx.i1;
    s.y = pick<2>(wy, 2, s.u) == 0 ? ly.i0 : ly.i1;
    return s;
}

Rgb Material::eval_selected(const Selection& s, const Uv&, const Vec3&, const Vec3& wi) const {
    const AngularWeights lights = light_interpolator().weights(wi);
    double u = s.u;
    return eval_sample(s.x, s.y, s.view,
                       lights.index[size_t(pick<3>(lights.weight.data(), lights.count, u))]);
}

LightSample Material::sample_selected(const Selection& s, const Uv& uv, const Vec3& wo, double xi1,
                                      double xi2) const {
    LightSample r = generic_sampler().sample_view(s.x, s.y, s.view, xi1, xi2);
    r.value = eval_selected(s, uv, wo, r.wi);
    if (r.pdf > 0) r.weight = r.value * static_cast<float>(1 / r.pdf);
    return r;
}

double Material::pdf_selected(const Selection& s, const Uv&, const Vec3&, const Vec3& wi) const {
    return generic_sampler().pdf_view(s.x, s.y, s.view, wi);
}

void Material::eval_stochastic_batch(std::span<const StochasticQuery> queries,
                                     std::span<Rgb> out) const {
    if (queries.size() != out.size())
        fail("eval_stochastic_batch: {} queries but {} outputs", queries.size(), out.size());
    for (size_t i = 0; i < queries.size(); ++i) {
        const StochasticQuery& q = queries[i];
        out[i] = ShadingPoint(*this, q.uv, q.wo, Filter::kStochastic, q.u).eval(q.wi);
    }
}

void Material::sample_stochastic_batch(std::span<const StochasticSampleQuery> queries,
                                       std::span<LightSample> out) const {
    if (queries.size() != out.size())
        fail("sample_stochastic_batch: {} queries but {} outputs", queries.size(), out.size());
    for (size_t i = 0; i < queries.size(); ++i) {
        const StochasticSampleQuery& q = queries[i];
        out[i] = ShadingPoint(*this, q.uv, q.wo, Filter::kStochastic, q.u).sample(q.xi1, q.xi2);
    }
}

// ---- ShadingPoint -----------------------------------------------------------------------------

ShadingPoint::ShadingPoint(const Material& material, const Uv& uv, const Vec3& wo, Filter filter,
                           double u, std::optional<double> light_u)
    : m_material(&material), m_uv(uv), m_wo(wo), m_filter(filter) {
    if (filter == Filter::kStochastic) {
        auto clamp = [](double x) { return x >= 0 ? std::min(x, 0x1.fffffffffffffp-1) : 0.0; };
        m_selection = material.select(uv, wo, clamp(u));  // (NaN → 0)
        if (light_u) m_selection.u = clamp(*light_u);
    }
}

Rgb ShadingPoint::eval(const Vec3& wi) const {
    if (!m_material) return {};
    if (m_filter == Filter::kDeterministic) return m_material->eval(m_uv, wi, m_wo);
    return m_material->eval_selected(m_selection, m_uv, m_wo, wi);
}

LightSample ShadingPoint::sample(double xi1, double xi2) const {
    if (!m_material) return {};
    if (m_filter == Filter::kDeterministic) return m_material->sample(m_uv, m_wo, xi1, xi2);
    return m_material->sample_selected(m_selection, m_uv, m_wo, xi1, xi2);
}

double ShadingPoint::pdf(const Vec3& wi) const {
    if (!m_material) return 0;
    if (m_filter == Filter::kDeterministic) return m_material->pdf(m_uv, m_wo, wi);
    return m_material->pdf_selected(m_selection, m_uv, m_wo, wi);
}

Rgb ShadingPoint::albedo() const {
    return m_material ? m_material->albedo(m_uv, m_wo) : Rgb{};
}

}  // namespace btf
