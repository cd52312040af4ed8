// SPDX-License-Identifier: MIT
#include "btf/codecs/perceptual/csf.h"

#include <kiss_fftnd.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <memory>

#include "btf/core/math.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::perceptual {

const Csf& achromatic_csf() {
    static const Csf csf{{{1.68025, 0.044888}, {1.31962, 0.116833}, {-1.99987, 0.159155}},
                         {{1.43125, 0.028047}, {1.46968, 0.137456}, {-1.90093, 0.159155}}};
    return csf;
}

const Csf& chromatic_csf() {
    static const Csf csf{{{0.56684, 0.059308}, {0.43316, 0.113673}},
                         {{0.42810, 0.032472}, {0.57190, 0.074796}}};
    return csf;
}

// ---- spatial ---------------------------------------------------------------------------------

namespace {

// Frequency of DFT bin k of n samples, in cycles per sample.
double bin_frequency(int k, int n) {
    return (k <= n / 2 ? k : k - n) / double(n);
}

struct FftDeleter {
    void operator()(void* cfg) const { kiss_fft_free(cfg); }
};
using FftPlan = std::unique_ptr<std::remove_pointer_t<kiss_fftnd_cfg>, FftDeleter>;

FftPlan plan(int width, int height, bool inverse) {
    const int dims[2] = {height, width};
    FftPlan p(kiss_fftnd_alloc(dims, 2, inverse ? 1 : 0, nullptr, nullptr));
    if (!p) fail("spatial CSF filter: cannot allocate a {}×{} FFT", width, height);
    return p;
}

}  // namespace

SpatialFilter::SpatialFilter(const std::vector<Gaussian>& mixture, double texels_per_degree,
                             int width, int height)
    : m_width(width), m_height(height) {
    check(width > 0 && height > 0, "spatial CSF filter: bad extent {}×{}", width, height);
    check(texels_per_degree > 0, "spatial CSF filter: resolution {} must be positive",
          texels_per_degree);
    m_transfer.resize(size_t(width) * height);
    for (int ky = 0; ky < height; ++ky) {
        const double fy = bin_frequency(ky, height);
        for (int kx = 0; kx < width; ++kx) {
            const double fx = bin_frequency(kx, width), f2 = fx * fx + fy * fy;
            double h = 0;
            for (const Gaussian& g : mixture) {
                const double s = g.sigma * texels_per_degree;
                h += g.weight * std::exp(-kPi * kPi * s * s * f2);
            }
            m_transfer[size_t(ky) * width + kx] = static_cast<float>(h);
        }
    }
}

void SpatialFilter::apply(factor::Matrix& textures) const {
    const int64_t texels = int64_t(m_width) * m_height;
    if (textures.rows() != texels)
        fail("spatial CSF filter: {} rows for {}×{} textures", textures.rows(), m_width, m_height);
    const int64_t cols = textures.cols();
    const float scale = 1.0f / static_cast<float>(texels);
    parallel_for(0, (cols + 1) / 2, [&](int64_t pair) {
        const int64_t c0 = 2 * pair, c1 = c0 + 1;
        const bool two = c1 < cols;
        const FftPlan forward = plan(m_width, m_height, false);
        const FftPlan backward = plan(m_width, m_height, true);
        std::vector<std::complex<float>> in(texels), spectrum(texels);
        for (int64_t t = 0; t < texels; ++t)
            in[t] = {textures(t, c0), two ? textures(t, c1) : 0.0f};
        kiss_fftnd(forward.get(), reinterpret_cast<const kiss_fft_cpx*>(in.data()),
                   reinterpret_cast<kiss_fft_cpx*>(spectrum.data()));
        for (int64_t t = 0; t < texels; ++t) spectrum[t] *= m_transfer[t] * scale;
        kiss_fftnd(backward.get(), reinterpret_cast<const kiss_fft_cpx*>(spectrum.data()),
                   reinterpret_cast<kiss_fft_cpx*>(in.data()));
        for (int64_t t = 0; t < texels; ++t) {
            textures(t, c0) = in[t].real();
            if (two) textures(t, c1) = in[t].imag();
        }
    });
}

// ---- angular ---------------------------------------------------------------------------------

Eigen::MatrixXd angular_kernel(const DirectionSet& set, double sigma_degrees) {
    check(sigma_degrees > 0, "angular CSF kernel: width {}° must be positive", sigma_degrees);
    const int n = set.size();
    Eigen::MatrixXd k(n, n);
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            const Vec3 &a = set.vector(i), &b = set.vector(j);
            // atan2 of |a × b| and a · b: accurate for small angles, unlike acos.
            const double angle = degrees(std::atan2(length(cross(a, b)), dot(a, b)));
            const double d = angle / sigma_degrees;
            k(i, j) = std::exp(-d * d);
        }
        k.row(i) /= k.row(i).sum();  // the diagonal term is 1, so the sum is ≥ 1
    }
    return k;
}

AngularFilter::AngularFilter(const std::vector<Gaussian>& mixture, double degrees_per_second,
                             const Sampling& sampling)
    : m_views(sampling.num_views()), m_lights(sampling.num_lights()) {
    check(degrees_per_second > 0, "angular CSF filter: speed {} must be positive",
          degrees_per_second);
    for (const Gaussian& g : mixture) {
        const double width = g.sigma * degrees_per_second;
        m_weights.push_back(g.weight);
        m_view_kernels.push_back(angular_kernel(sampling.views, width).cast<float>());
        m_light_kernels.push_back(angular_kernel(sampling.lights, width).cast<float>());
    }
}

void AngularFilter::apply(factor::Matrix& y, bool transpose) const {
    const int64_t rows = int64_t(m_views) * m_lights;
    if (y.rows() != rows)
        fail("angular CSF filter: {} rows for {} views × {} lights", y.rows(), m_views, m_lights);
    using Grid = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    parallel_for(0, y.cols(), [&](int64_t c) {
        Grid in(m_views, m_lights), out = Grid::Zero(m_views, m_lights);
        for (int64_t r = 0; r < rows; ++r) in.data()[r] = y(r, c);
        // A column is a views × lights grid Y: (K_v ⊗ K_l) vec(Y) = vec(K_v Y K_lᵀ).
        for (size_t i = 0; i < m_weights.size(); ++i) {
            const float w = static_cast<float>(m_weights[i]);
            if (transpose)
                out.noalias() += w * (m_view_kernels[i].transpose() * in * m_light_kernels[i]);
            else
                out.noalias() += w * (m_view_kernels[i] * in * m_light_kernels[i].transpose());
        }
        for (int64_t r = 0; r < rows; ++r) y(r, c) = out.data()[r];
    });
}

Eigen::MatrixXd AngularFilter::matrix() const {
    const int64_t n = int64_t(m_views) * m_lights;
    Eigen::MatrixXd t = Eigen::MatrixXd::Zero(n, n);
    for (size_t i = 0; i < m_weights.size(); ++i)
        for (int v = 0; v < m_views; ++v)
            for (int w = 0; w < m_views; ++w)
                for (int l = 0; l < m_lights; ++l)
                    for (int m = 0; m < m_lights; ++m)
                        t(int64_t(v) * m_lights + l, int64_t(w) * m_lights + m) +=
                            m_weights[i] * m_view_kernels[i](v, w) * m_light_kernels[i](l, m);
    return t;
}

// ---- the codec's transforms ------------------------------------------------------------------

CsfTransforms::CsfTransforms(const Sampling& sampling, int width, int height,
                             const Viewing& viewing) {
    for (const Csf* csf : {&achromatic_csf(), &chromatic_csf()}) {
        m_spatial.emplace_back(csf->spatial, viewing.resolution, width, height);
        m_angular.emplace_back(csf->angular, viewing.speed, sampling);
    }
}

void CsfTransforms::left(int matrix, factor::Matrix& y, bool transpose) const {
    angular(matrix).apply(y, transpose);
}

void CsfTransforms::right(int matrix, factor::Matrix& z, bool) const {
    spatial(matrix).apply(z);  // symmetric: T_uᵀ = T_u
}

}  // namespace btf::perceptual
