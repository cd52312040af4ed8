// SPDX-License-Identifier: MIT
#include "btf/codecs/material_source.h"

#include <cmath>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/util/collective.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {

MaterialSource::MaterialSource(std::shared_ptr<const Material> material, const std::string& codec,
                               std::filesystem::path path, bool hdr)
    : m_material(std::move(material)) {
    check(m_material != nullptr, "MaterialSource: no material");
    m_info.format = "btfkit package (" + codec + ")";
    m_info.path = std::move(path);
    m_info.hdr = hdr;
}

void MaterialSource::read_image(int view, int light, Image& out) const {
    const Sampling& s = sampling();
    if (view < 0 || light < 0 || view >= s.num_views() || light >= s.num_lights())
        fail("{}: image (view {}, light {}) outside {} views × {} lights",
             m_info.path.empty() ? m_info.format : m_info.path.string(), view, light, s.num_views(),
             s.num_lights());
    const int w = width(), h = height();
    out.reshape(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) out.set_rgb(x, y, m_material->eval_sample(x, y, view, light));
}

std::unique_ptr<BtfSource> open_package_or_source(const std::filesystem::path& path,
                                                  const OpenOptions& options) {
    if (probe_package(path)) return open_package_source(path);
    return open_source(path, options);
}

std::unique_ptr<MaterialSource> open_package_source(const std::filesystem::path& path) {
    const Package package = read_package(path);
    std::shared_ptr<const Material> material;
    try {
        material = open_material(package);
    } catch (const Cancelled&) {
        throw;
    } catch (const Error& e) {
        fail("{}: {}", path.string(), e.what());
    }
    const auto hdr = package.header.find("hdr");
    const bool is_hdr = hdr != package.header.end() && hdr->is_boolean() && hdr->get<bool>();
    return std::make_unique<MaterialSource>(std::move(material), package.codec(), path, is_hdr);
}

double sample_rmse(const BtfSource& reference, const Material& material, Progress& progress) {
    const std::string name =
        reference.info().path.empty() ? reference.info().format : reference.info().path.string();
    const Sampling& s = reference.sampling();
    check(material.width() == reference.width() && material.height() == reference.height(),
          "{}: the material is {}×{} texels, the reference {}×{}", name, material.width(),
          material.height(), reference.width(), reference.height());
    check(material.sampling().num_views() == s.num_views() &&
              material.sampling().num_lights() == s.num_lights(),
          "{}: the material has {} views × {} lights, the reference {} × {}", name,
          material.sampling().num_views(), material.sampling().num_lights(), s.num_views(),
          s.num_lights());
    const int64_t images = s.num_images();
    const int nl = s.num_lights();
    const int w = reference.width(), h = reference.height();
    // One sum per image, added in image order afterwards: the same result for any thread count.
    // Across ranks (util/collective.h), each reads its share of the views and the sums are
    // completed by adding the ranks' (zeros where a rank read nothing): the same result again.
    Collective* ranks = current_collective();
    const auto [first_view, last_view] =
        ranks ? rank_share(s.num_views(), ranks->rank(), ranks->size())
              : std::pair<int64_t, int64_t>(0, s.num_views());
    std::vector<double> sums(static_cast<size_t>(images), 0.0);
    progress.begin("measuring error", static_cast<uint64_t>((last_view - first_view) * nl));
    together(ranks, [&] {
        parallel_for(first_view * nl, last_view * nl, [&](int64_t i) {
            const int view = static_cast<int>(i / nl), light = static_cast<int>(i % nl);
            Image image;
            reference.read_image(view, light, image);
            double sum = 0;
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x) {
                    const Rgb a = image.rgb(x, y);
                    const Rgb b = material.eval_sample(x, y, view, light);
                    const double dr = double(a.r) - b.r, dg = double(a.g) - b.g,
                                 db = double(a.b) - b.b;
                    sum += dr * dr + dg * dg + db * db;
                }
            sums[static_cast<size_t>(i)] = sum;
            progress.advance();
        });
    });
    progress.finish();
    if (ranks) ranks->sum(sums.data(), images);
    double total = 0;
    for (double v : sums) total += v;
    const double count = double(images) * double(w) * double(h) * 3.0;
    return count > 0 ? std::sqrt(total / count) : 0.0;
}

}  // namespace btf
