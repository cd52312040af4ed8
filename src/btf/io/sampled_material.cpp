// SPDX-License-Identifier: MIT
#include "btf/io/sampled_material.h"

#include <fmt/format.h>
#include "btf/core/btf_lookup.h"
#include "btf/core/image.h"
#include "btf/io/open.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/parallel.h"

namespace btf {

SampledMaterial::SampledMaterial(const BtfSource& source, int64_t memory_limit, Progress& progress)
    : m_width(source.width()), m_height(source.height()), m_sampling(source.sampling()) {
    const int64_t images = m_sampling.num_images();
    const int64_t per_image = int64_t(m_width) * m_height * 3;
    const int64_t bytes = images * per_image * int64_t(sizeof(uint16_t));
    if (bytes > memory_limit)
        throw Error(fmt::format(
            "{}: holding its {} images uncompressed takes {:.1f} GiB, more than the limit of "
            "{:.1f} GiB; compress it (btf compress) and use the package",
            source.info().path.empty() ? std::string("synthetic material")
                                       : source.info().path.string(),
            images, double(bytes) / double(int64_t(1) << 30),
            double(memory_limit) / double(int64_t(1) << 30)));
    m_views = std::make_unique<AngularInterpolator>(m_sampling.views);
    m_lights = std::make_unique<AngularInterpolator>(m_sampling.lights);
    m_samples.resize(size_t(images * per_image));
    progress.begin("reading images", uint64_t(images));
    parallel_for(0, images, [&](int64_t i) {
        Image image;
        const int view = int(i / m_sampling.num_lights()), light = int(i % m_sampling.num_lights());
        source.read_image(view, light, image);
        uint16_t* out = m_samples.data() + i * per_image;
        for (int y = 0; y < m_height; ++y)
            for (int x = 0; x < m_width; ++x)
                for (int c = 0; c < 3; ++c)
                    out[(int64_t(y) * m_width + x) * 3 + c] = to_half(image.at(x, y, c));
        progress.advance();
    });
    progress.finish();
}

Rgb SampledMaterial::eval_sample(int x, int y, int view, int light) const {
    const uint16_t* p =
        m_samples.data() +
        (((int64_t(view) * m_sampling.num_lights() + light) * m_height + y) * m_width + x) * 3;
    return {from_half(p[0]), from_half(p[1]), from_half(p[2])};
}

Rgb SampledMaterial::eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const {
    return lookup6d(
        uv, m_width, m_height, m_views->weights(wo), m_lights->weights(wi),
        [&](int x, int y, int view, int light) { return eval_sample(x, y, view, light); });
}

std::unique_ptr<SampledMaterial> open_sampled_material(const std::filesystem::path& path,
                                                       Progress& progress) {
    const std::unique_ptr<BtfSource> source = open_source(path);
    return std::make_unique<SampledMaterial>(*source, int64_t(4) << 30, progress);
}

}  // namespace btf
