// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/angular_levels.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <limits>

#include "btf/core/angular_interpolator.h"
#include "btf/util/error.h"

namespace btf::factor {

std::vector<int> farthest_point_order(const DirectionSet& set) {
    const int n = set.size();
    std::vector<int> order;
    if (n == 0) return order;
    // The smallest angle to the chosen directions, as its cosine (largest cosine = closest).
    std::vector<double> closest(size_t(n), -std::numeric_limits<double>::infinity());
    std::vector<bool> chosen(size_t(n), false);
    int next = 0;
    for (int i = 1; i < n; ++i)
        if (set.vector(i).z > set.vector(next).z) next = i;
    for (int step = 0; step < n; ++step) {
        order.push_back(next);
        chosen[size_t(next)] = true;
        int best = -1;
        for (int i = 0; i < n; ++i) {
            if (chosen[size_t(i)]) continue;
            closest[size_t(i)] = std::max(closest[size_t(i)], dot(set.vector(i), set.vector(next)));
            if (best < 0 || closest[size_t(i)] < closest[size_t(best)]) best = i;
        }
        next = best;
    }
    return order;
}

std::vector<AngularLevel> nested_angular_levels(const Sampling& sampling, int count) {
    const std::vector<int> views = farthest_point_order(sampling.views);
    const std::vector<int> lights = farthest_point_order(sampling.lights);
    std::vector<AngularLevel> levels;
    for (int j = 1; j <= count && j < 31; ++j) {
        const int step = 1 << j;
        const int nv = (sampling.num_views() + step - 1) / step;
        const int nl = (sampling.num_lights() + step - 1) / step;
        if (nv < kMinAngularDirections || nl < kMinAngularDirections) break;
        AngularLevel level;
        level.views.assign(views.begin(), views.begin() + nv);
        level.lights.assign(lights.begin(), lights.begin() + nl);
        std::sort(level.views.begin(), level.views.end());
        std::sort(level.lights.begin(), level.lights.end());
        levels.push_back(std::move(level));
    }
    return levels;
}

namespace {

// U (full × coarse) of one direction set and its least-squares inverse D = (UᵀU)⁻¹Uᵀ.
void set_resampling(const DirectionSet& set, const std::vector<int>& subset, const char* what,
                    Eigen::MatrixXd& up, Eigen::MatrixXd& down) {
    check(int(subset.size()) >= kMinAngularDirections, "angular level: {} {} (at least {} needed)",
          subset.size(), what, kMinAngularDirections);
    std::vector<bool> seen(size_t(set.size()), false);
    for (int i : subset) {
        check(i >= 0 && i < set.size(), "angular level: {} index {} outside 0..{}", what, i,
              set.size() - 1);
        check(!seen[size_t(i)], "angular level: {} index {} repeated", what, i);
        seen[size_t(i)] = true;
    }
    const AngularInterpolator coarse(set.subset(subset, set.name() + "/level"));
    up = Eigen::MatrixXd::Zero(set.size(), Eigen::Index(subset.size()));
    for (int i = 0; i < set.size(); ++i) {
        const AngularWeights w = coarse.weights(set.vector(i));
        for (int k = 0; k < w.count; ++k) up(i, w.index[size_t(k)]) += w.weight[size_t(k)];
    }
    const Eigen::MatrixXd gram = up.transpose() * up;
    down = gram.ldlt().solve(up.transpose());
}

}  // namespace

AngularResampler::AngularResampler(const Sampling& sampling, const AngularLevel& level,
                                   int channels)
    : m_channels(channels) {
    set_resampling(sampling.views, level.views, "views", m_up_views, m_down_views);
    set_resampling(sampling.lights, level.lights, "lights", m_up_lights, m_down_lights);
    m_full_rows = int64_t(sampling.num_views()) * sampling.num_lights() * channels;
    m_coarse_rows = int64_t(level.views.size()) * int64_t(level.lights.size()) * channels;
}

Eigen::MatrixXd AngularResampler::apply(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                        const Eigen::MatrixXd& x) const {
    const Eigen::Index in_v = a.cols(), in_l = b.cols(), out_v = a.rows(), out_l = b.rows();
    check(x.rows() == in_v * in_l * m_channels, "angular level: a column of {} rows, expected {}",
          x.rows(), in_v * in_l * m_channels);
    Eigen::MatrixXd y(out_v * out_l * m_channels, x.cols());
    Eigen::MatrixXd f(in_v, in_l);
    for (Eigen::Index col = 0; col < x.cols(); ++col)
        for (int c = 0; c < m_channels; ++c) {
            for (Eigen::Index v = 0; v < in_v; ++v)
                for (Eigen::Index l = 0; l < in_l; ++l)
                    f(v, l) = x((v * in_l + l) * m_channels + c, col);
            const Eigen::MatrixXd g = a * f * b.transpose();
            for (Eigen::Index v = 0; v < out_v; ++v)
                for (Eigen::Index l = 0; l < out_l; ++l)
                    y((v * out_l + l) * m_channels + c, col) = g(v, l);
        }
    return y;
}

Eigen::MatrixXd AngularResampler::upsample(const Eigen::MatrixXd& coarse) const {
    return apply(m_up_views, m_up_lights, coarse);
}

Eigen::MatrixXd AngularResampler::downsample(const Eigen::MatrixXd& full) const {
    return apply(m_down_views, m_down_lights, full);
}

}  // namespace btf::factor
