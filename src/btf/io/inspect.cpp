// SPDX-License-Identifier: MIT
#include "btf/io/inspect.h"

#include <cmath>
#include <limits>
#include <vector>

#include "btf/core/color.h"
#include "btf/util/parallel.h"

namespace btf {

ValueStats value_stats(const BtfSource& source, int64_t max_images, Progress& progress) {
    const int64_t total = source.sampling().num_images();
    const int64_t count = (max_images <= 0 || max_images >= total) ? total : max_images;
    struct Partial {
        int64_t values = 0, non_finite = 0;
        std::array<double, 3> min{}, max{}, sum{};
        double luminance = 0;
    };
    std::vector<Partial> partials(count);
    progress.begin("statistics", uint64_t(count));
    parallel_for(0, count, [&](int64_t i) {
        // Evenly spread image indices; view-major order as in the sampling.
        const int64_t image = count == total ? i : (i * total) / count;
        const int view = int(image / source.num_lights());
        const int light = int(image % source.num_lights());
        Image img;
        source.read_image(view, light, img);
        Partial p;
        p.min.fill(std::numeric_limits<double>::infinity());
        p.max.fill(-std::numeric_limits<double>::infinity());
        for (int64_t t = 0; t < img.num_pixels(); ++t) {
            const float* v = img.data() + t * 3;
            bool finite = true;
            for (int c = 0; c < 3; ++c) finite &= std::isfinite(v[c]);
            if (!finite) {
                ++p.non_finite;
                continue;
            }
            for (int c = 0; c < 3; ++c) {
                p.min[c] = std::min(p.min[c], double(v[c]));
                p.max[c] = std::max(p.max[c], double(v[c]));
                p.sum[c] += v[c];
            }
            p.luminance += luminance({v[0], v[1], v[2]});
            ++p.values;
        }
        partials[i] = p;
        progress.advance();
    });
    progress.finish();
    // Reduce in image order so the result does not depend on the thread count.
    ValueStats stats;
    stats.images = count;
    stats.min.fill(std::numeric_limits<double>::infinity());
    stats.max.fill(-std::numeric_limits<double>::infinity());
    std::array<double, 3> sum{};
    double lum = 0;
    for (const Partial& p : partials) {
        stats.values += p.values;
        stats.non_finite += p.non_finite;
        for (int c = 0; c < 3; ++c) {
            stats.min[c] = std::min(stats.min[c], p.min[c]);
            stats.max[c] = std::max(stats.max[c], p.max[c]);
            sum[c] += p.sum[c];
        }
        lum += p.luminance;
    }
    if (stats.values > 0) {
        for (int c = 0; c < 3; ++c) stats.mean[c] = sum[c] / double(stats.values);
        stats.mean_luminance = lum / double(stats.values);
    }
    return stats;
}

uint64_t disk_usage(const std::filesystem::path& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_regular_file(path, ec)) return fs::file_size(path, ec);
    uint64_t bytes = 0;
    if (fs::is_directory(path, ec))
        for (auto it = fs::recursive_directory_iterator(path, ec);
             !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
            if (it->is_regular_file(ec)) bytes += it->file_size(ec);
    return bytes;
}

}  // namespace btf
