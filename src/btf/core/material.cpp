#include "btf/core/material.h"

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

}  // namespace detail

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

double Material::pdf(const Uv& uv, const Vec3& wo, const Vec3& wi) const {
    return generic_sampler().pdf(uv, wo, wi);
}

Rgb Material::albedo(const Uv& uv, const Vec3& wo) const {
    return quadrature_albedo(*this, uv, wo);
}

}  // namespace btf
