// SPDX-License-Identifier: MIT
#include "btf/io/slice.h"

#include "btf/core/angular_interpolator.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {

Image slice_image(const BtfSource& source, const Vec3& wi, const Vec3& wo) {
    const AngularInterpolator views(source.sampling().views);
    const AngularInterpolator lights(source.sampling().lights);
    const AngularWeights vw = views.weights(wo);
    const AngularWeights lw = lights.weights(wi);
    Image out(source.width(), source.height(), 3);
    Image img;
    for (int a = 0; a < vw.count; ++a)
        for (int b = 0; b < lw.count; ++b) {
            const float w = vw.weight[a] * lw.weight[b];
            if (w == 0) continue;
            source.read_image(vw.index[a], lw.index[b], img);
            for (size_t i = 0; i < out.values().size(); ++i) out.data()[i] += w * img.data()[i];
        }
    return out;
}

Image abrdf_image(const BtfSource& source, int x, int y, int scale, Progress& progress) {
    check(x >= 0 && x < source.width() && y >= 0 && y < source.height(),
          "{}: texel ({}, {}) is outside the {}x{} texture", source.info().path.string(), x, y,
          source.width(), source.height());
    check(scale >= 1 && scale <= 64, "ABRDF scale {} is outside [1, 64]", scale);
    const int nv = source.num_views(), nl = source.num_lights();
    Image out(nl * scale, nv * scale, 3);
    progress.begin("reading images", uint64_t(nv) * nl);
    parallel_for(0, int64_t(nv) * nl, [&](int64_t i) {
        const int v = int(i / nl), l = int(i % nl);
        Image img;
        source.read_image(v, l, img);
        const Rgb value = img.rgb(x, y);
        for (int dy = 0; dy < scale; ++dy)
            for (int dx = 0; dx < scale; ++dx) out.set_rgb(l * scale + dx, v * scale + dy, value);
        progress.advance();
    });
    progress.finish();
    return out;
}

}  // namespace btf
