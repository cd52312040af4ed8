// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/parametrization.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#ifdef __AVX2__
#include <immintrin.h>
#endif

#include "btf/core/angular_interpolator.h"
#include "btf/core/image.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::mlvq {

namespace {

constexpr const char* kGridName = "mlvq grid";
// Resampling terms whose weight is below this fraction of the sample's total are dropped.
constexpr double kNegligible = 1e-7;

typedef float Lanes __attribute__((vector_size(32)));
constexpr int kLanes = 8;
inline Lanes load(const float* p) {
    Lanes v;
    std::memcpy(&v, p, sizeof v);
    return v;
}

// The query conventions of AngularInterpolator: z clamped to ≥ 0 (NaN z → 0), no direction →
// +x on the horizon; otherwise normalized.
Vec3 prepare(const Vec3& d) {
    double x = d.x, y = d.y;
    double z = d.z > 0 ? d.z : 0.0;
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) return {1, 0, 0};
    const double m = std::max({std::abs(x), std::abs(y), z});
    if (!(m > 0)) return {1, 0, 0};
    const double inv_m = 1 / m;  // scaling first keeps tiny and huge vectors representable
    x *= inv_m, y *= inv_m, z *= inv_m;
    const double inv_len = 1 / std::sqrt(x * x + y * y + z * z);
    return {x * inv_len, y * inv_len, z * inv_len};
}

double wrap_2pi(double phi) {
    if (phi < 0) phi += 2 * kPi;
    if (phi >= 2 * kPi) phi -= 2 * kPi;
    return phi;
}

// Light coordinates in the onion frame whose view azimuth has cosine c and sine s: α and u = sin β
// of a prepared (unit, upper-hemisphere) light vector.
// atan2 to within 7e-9 rad (|atan(a) − a·P(a²)| ≤ 6.3e-9 on [0, 1], P a degree-8 polynomial
// fitted here by least squares on Chebyshev nodes), with the octant reduction of atan2: a few
// times faster than libm's, which dominated the evaluator's lookup. Same conventions as
// std::atan2 (result in [−π, π]; atan2(0, 0) = 0).
double fast_atan2(double y, double x) {
    const double ax = std::abs(x), ay = std::abs(y);
    const double hi = std::max(ax, ay), lo = std::min(ax, ay);
    if (!(hi > 0)) return std::atan2(y, x);  // zeros (signed) and NaN as libm has them
    const double a = lo / hi, t = a * a;
    double p = 0.0024658027090396204;
    p = p * t - 0.014447824985279543;
    p = p * t + 0.039879561877043009;
    p = p * t - 0.072459898738032782;
    p = p * t + 0.1050621951777013;
    p = p * t - 0.1416398149209013;
    p = p * t + 0.19986477628185906;
    p = p * t - 0.33332653297665071;
    p = p * t + 0.99999990456937238;
    double r = a * p;
    if (ay > ax) r = kPi / 2 - r;
    if (x < 0) r = kPi - r;
    return y < 0 ? -r : r;
}

void onion_of_prepared(const Vec3& i, double c, double s, double& alpha, double& u,
                       bool fast = false) {
    u = std::clamp(-s * i.x + c * i.y, -1.0, 1.0);  // · e_β
    const double a = -c * i.x - s * i.y;            // · e_α
    alpha = (a == 0 && i.z == 0) ? 0.0 : fast ? fast_atan2(a, i.z) : std::atan2(a, i.z);
}

// View coordinates of a prepared view vector, and the cosine and sine of its azimuth (the
// azimuth of the normal is 0).
void view_of_prepared(const Vec3& o, double& theta, double& phi, double& c, double& s,
                      bool fast = false) {
    const double rho = std::sqrt(o.x * o.x + o.y * o.y);
    theta = fast ? fast_atan2(rho, o.z) : std::atan2(rho, o.z);
    if (rho > 0) {
        phi = wrap_2pi(fast ? fast_atan2(o.y, o.x) : std::atan2(o.y, o.x));
        c = o.x / rho, s = o.y / rho;
    } else {
        phi = 0, c = 1, s = 0;
    }
}

// Linear weights of the fractional index x on samples 0 … n − 1 (clamped).
AxisWeights clamped_axis(double x, int n) {
    if (!(x > 0)) x = 0;
    if (x > n - 1) x = n - 1;
    const int i0 = std::min(static_cast<int>(x), n - 2);
    const float w1 = static_cast<float>(x - i0);
    return {{i0, i0 + 1}, {1.0f - w1, w1}};
}

// Linear weights of the fractional index x on n periodic samples.
AxisWeights periodic_axis(double x, int n) {
    if (n == 1) return {{0, 0}, {1.0f, 0.0f}};
    if (!std::isfinite(x)) x = 0;
    const double f = std::floor(x);
    // The evaluator's φv is in [0, n]: a subtraction or two there (not an integer division,
    // tens of cycles), fmod (slow) beyond.
    int i0;
    if (f >= 0 && f <= 2.0 * n) {
        i0 = static_cast<int>(f);
        if (i0 >= n) i0 -= n;
        if (i0 >= n) i0 -= n;
    } else {
        i0 = static_cast<int>(std::fmod(f, double(n)));
    }
    if (i0 < 0) i0 += n;
    if (i0 >= n) i0 -= n;
    const float w1 = static_cast<float>(std::clamp(x - f, 0.0, 1.0));
    return {{i0, i0 + 1 == n ? 0 : i0 + 1}, {1.0f - w1, w1}};
}

void light_axes(const MlvqGrid& g, double alpha, double u, MlvqWeights& w) {
    w.alpha = clamped_axis((alpha + kPi / 2) / kPi * (g.n_alpha - 1), g.n_alpha);
    w.beta = clamped_axis((u + 1) / 2 * (g.n_beta - 1), g.n_beta);
}

void view_axes(const MlvqGrid& g, double theta, double phi, MlvqWeights& w) {
    w.theta_v = clamped_axis(theta / (kPi / 2) * (g.n_theta_v - 1), g.n_theta_v);
    w.phi_v = periodic_axis(phi / (2 * kPi) * g.n_phi_v, g.n_phi_v);
}

// The axis weights of lookup_views() and lookup_lights(): the fractional index by a
// multiplication where weights_of() divides (a division's latency is several multiplications'),
// so that an index may differ from lookup()'s in its last bit.
struct AxisScales {
    double alpha, beta, theta, phi;
    explicit AxisScales(const MlvqGrid& g)
        : alpha((g.n_alpha - 1) * (1 / kPi)),
          beta(0.5 * (g.n_beta - 1)),
          theta((g.n_theta_v - 1) * (2 / kPi)),
          phi(g.n_phi_v * (0.5 / kPi)) {}
};

void view_axes_scaled(const MlvqGrid& g, const AxisScales& k, double theta, double phi,
                      MlvqWeights& w) {
    w.theta_v = clamped_axis(theta * k.theta, g.n_theta_v);
    w.phi_v = periodic_axis(phi * k.phi, g.n_phi_v);
}

void light_axes_scaled(const MlvqGrid& g, const AxisScales& k, double alpha, double u,
                       MlvqWeights& w) {
    w.alpha = clamped_axis((alpha + kPi / 2) * k.alpha, g.n_alpha);
    w.beta = clamped_axis((u + 1) * k.beta, g.n_beta);
}

MlvqWeights weights_of(const MlvqGrid& g, double alpha, double u, double theta, double phi) {
    MlvqWeights w;
    light_axes(g, alpha, u, w);
    view_axes(g, theta, phi, w);
    return w;
}

std::string source_name(const BtfSource& source) {
    if (!source.info().path.empty()) return source.info().path.string();
    return source.info().format.empty() ? std::string("source") : source.info().format;
}

}  // namespace

// ---- grid --------------------------------------------------------------------------------------

void MlvqGrid::validate() const {
    auto axis = [](const char* name, int n, int least, const char* why) {
        if (n < least) fail("{}: {} = {} is below {} ({})", kGridName, name, n, least, why);
        if (n > kMaxAxis) fail("{}: {} = {} is above the limit {}", kGridName, name, n, kMaxAxis);
    };
    axis("n_alpha", n_alpha, 3, "with 2 slices both lie on the horizon");
    axis("n_beta", n_beta, 3, "with 2 samples per slice both are the poles on the horizon");
    axis("n_theta_v", n_theta_v, 2, "the view elevations span 0 to 90 degrees");
    axis("n_phi_v", n_phi_v, 1, "1 means isotropic");
    if (n_phi_v == 2)
        fail(
            "{}: n_phi_v = 2 cannot tell view azimuths φ and −φ apart (both blend the samples "
            "at 0 and 180 degrees alike); use 1 (isotropic) or at least 3",
            kGridName);
    if (samples() > kMaxSamples)
        fail("{}: {}x{}x{}x{} = {} samples per texel and channel exceed the limit {}", kGridName,
             n_phi_v, n_theta_v, n_alpha, n_beta, samples(), kMaxSamples);
}

double MlvqGrid::alpha(int i) const {
    return -kPi / 2 + kPi * i / (n_alpha - 1);
}

double MlvqGrid::sin_beta(int j) const {
    if (j == 0) return -1.0;
    if (j == n_beta - 1) return 1.0;
    return -1.0 + 2.0 * j / (n_beta - 1);
}

double MlvqGrid::beta(int j) const {
    return std::asin(sin_beta(j));
}

double MlvqGrid::theta_v(int k) const {
    return (kPi / 2) * k / (n_theta_v - 1);
}

double MlvqGrid::phi_v(int m) const {
    return 2 * kPi * m / n_phi_v;
}

double MlvqGrid::light_weight(int i, int j) const {
    const double d_alpha = kPi / (n_alpha - 1), d_u = 2.0 / (n_beta - 1);
    const double ta = (i == 0 || i == n_alpha - 1) ? 0.5 : 1.0;
    const double tb = (j == 0 || j == n_beta - 1) ? 0.5 : 1.0;
    return d_alpha * d_u * ta * tb;
}

// ---- mapping -----------------------------------------------------------------------------------

OnionFrame::OnionFrame(double phi_v) : OnionFrame(std::cos(phi_v), std::sin(phi_v)) {}

OnionAngles onion_from_direction(const Vec3& wi, double phi_v) {
    double alpha = 0, u = 0;
    onion_of_prepared(prepare(wi), std::cos(phi_v), std::sin(phi_v), alpha, u);
    return {alpha, std::asin(u)};
}

Vec3 direction_from_onion_u(double alpha, double sin_beta, double phi_v) {
    return direction_from_onion_u(alpha, sin_beta, OnionFrame(phi_v));
}

void sin_cos_half_pi(double a, double& sin_a, double& cos_a) {
    if (!(std::abs(a) <= kPi / 2 + 1e-9)) {
        sin_a = std::sin(a), cos_a = std::cos(a);
        return;
    }
    // Half angle h, |h| ≤ π/4: Taylor series of sin h to h¹⁵ and of cos h to h¹⁶ (the next
    // terms are below 5e-17), then the double-angle formulas; the cosine as a product, which
    // keeps it accurate near ±π/2 where it vanishes.
    const double h = 0.5 * a, t = h * h;
    double ps = -1.0 / 1307674368000, pc = 1.0 / 20922789888000;
    ps = ps * t + 1.0 / 6227020800, pc = pc * t - 1.0 / 87178291200;
    ps = ps * t - 1.0 / 39916800, pc = pc * t + 1.0 / 479001600;
    ps = ps * t + 1.0 / 362880, pc = pc * t - 1.0 / 3628800;
    ps = ps * t - 1.0 / 5040, pc = pc * t + 1.0 / 40320;
    ps = ps * t + 1.0 / 120, pc = pc * t - 1.0 / 720;
    ps = ps * t - 1.0 / 6, pc = pc * t + 1.0 / 24;
    pc = pc * t - 0.5;
    const double sh = h + h * t * ps, ch = 1 + t * pc;
    sin_a = 2 * sh * ch;
    cos_a = (ch - sh) * (ch + sh);
}

Vec3 direction_from_onion_u(double alpha, double sin_beta, const OnionFrame& f) {
    const double u = std::clamp(sin_beta, -1.0, 1.0);
    const double cb = std::sqrt(std::max(0.0, 1 - u * u));
    double sa, ca;
    sin_cos_half_pi(alpha, sa, ca);
    return f.e_beta * u + f.e_alpha * (sa * cb) + f.n * (ca * cb);
}

Vec3 direction_from_onion(const OnionAngles& angles, double phi_v) {
    const OnionFrame f(phi_v);
    const double cb = std::cos(angles.beta);
    return f.e_beta * std::sin(angles.beta) + f.e_alpha * (std::sin(angles.alpha) * cb) +
           f.n * (std::cos(angles.alpha) * cb);
}

MlvqCoordinates to_mlvq(const Vec3& wi, const Vec3& wo) {
    MlvqCoordinates out;
    double c = 1, s = 0, u = 0;
    view_of_prepared(prepare(wo), out.theta_v, out.phi_v, c, s);
    onion_of_prepared(prepare(wi), c, s, out.alpha, u);
    out.beta = std::asin(u);
    return out;
}

void from_mlvq(const MlvqCoordinates& c, Vec3& wi, Vec3& wo) {
    wo = Direction{c.theta_v, c.phi_v}.vector();
    wi = direction_from_onion({c.alpha, c.beta}, c.phi_v);
}

// ---- lookup ------------------------------------------------------------------------------------

MlvqWeights lookup(const MlvqGrid& grid, const MlvqCoordinates& c) {
    return weights_of(grid, c.alpha, std::sin(c.beta), c.theta_v, c.phi_v);
}

ViewLookup lookup_view(const MlvqGrid& grid, const Vec3& wo) {
    double theta = 0, phi = 0, c = 1, s = 0;
    view_of_prepared(prepare(wo), theta, phi, c, s, true);
    ViewLookup out{{}, OnionFrame(c, s)};
    view_axes(grid, theta, phi, out.weights);
    return out;
}

MlvqWeights lookup(const MlvqGrid& grid, const Vec3& wi, const Vec3& wo) {
    double theta = 0, phi = 0, c = 1, s = 0, alpha = 0, u = 0;
    // The evaluator's inner loop: angles through fast_atan2 (weights change by < 1e-8).
    view_of_prepared(prepare(wo), theta, phi, c, s, true);
    onion_of_prepared(prepare(wi), c, s, alpha, u, true);
    return weights_of(grid, alpha, u, theta, phi);
}

#ifdef __AVX2__
namespace {

// fast_atan2 on four lanes whose |x|, |y| are not both 0.
__m256d fast_atan2(__m256d y, __m256d x) {
    const __m256d sign = _mm256_set1_pd(-0.0);
    const __m256d ax = _mm256_andnot_pd(sign, x), ay = _mm256_andnot_pd(sign, y);
    const __m256d hi = _mm256_max_pd(ax, ay), lo = _mm256_min_pd(ax, ay);
    const __m256d a = _mm256_div_pd(lo, hi), t = _mm256_mul_pd(a, a);
    __m256d p = _mm256_set1_pd(0.0024658027090396204);
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(-0.014447824985279543));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(0.039879561877043009));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(-0.072459898738032782));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(0.1050621951777013));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(-0.1416398149209013));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(0.19986477628185906));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(-0.33332653297665071));
    p = _mm256_fmadd_pd(p, t, _mm256_set1_pd(0.99999990456937238));
    __m256d r = _mm256_mul_pd(a, p);
    r = _mm256_blendv_pd(r, _mm256_sub_pd(_mm256_set1_pd(kPi / 2), r),
                         _mm256_cmp_pd(ay, ax, _CMP_GT_OQ));
    r = _mm256_blendv_pd(r, _mm256_sub_pd(_mm256_set1_pd(kPi), r), x);  // sign bit of x
    return _mm256_xor_pd(r, _mm256_and_pd(y, sign));
}

struct Lanes3 {
    __m256d x, y, z;
};

Lanes3 load3(const Vec3* v) {
    return {_mm256_setr_pd(v[0].x, v[1].x, v[2].x, v[3].x),
            _mm256_setr_pd(v[0].y, v[1].y, v[2].y, v[3].y),
            _mm256_setr_pd(v[0].z, v[1].z, v[2].z, v[3].z)};
}

// prepare() of four lanes; `regular` loses the lanes prepare() treats specially.
Lanes3 prepare(Lanes3 d, __m256d& regular) {
    const __m256d zero = _mm256_setzero_pd(), sign = _mm256_set1_pd(-0.0);
    d.z = _mm256_max_pd(d.z, zero);
    const __m256d limit = _mm256_set1_pd(1.7976931348623157e308);
    const __m256d ax = _mm256_andnot_pd(sign, d.x), ay = _mm256_andnot_pd(sign, d.y);
    // Finite lanes (NaN compares false; a NaN z is 0 by now, as in prepare()) with a non-zero
    // scale.
    regular = _mm256_and_pd(regular, _mm256_cmp_pd(ax, limit, _CMP_LE_OQ));
    regular = _mm256_and_pd(regular, _mm256_cmp_pd(ay, limit, _CMP_LE_OQ));
    regular = _mm256_and_pd(regular, _mm256_cmp_pd(d.z, limit, _CMP_LE_OQ));
    __m256d m = _mm256_max_pd(_mm256_max_pd(ax, ay), d.z);
    regular = _mm256_and_pd(regular, _mm256_cmp_pd(m, zero, _CMP_GT_OQ));
    m = _mm256_blendv_pd(_mm256_set1_pd(1), m, regular);
    const __m256d inv_m = _mm256_div_pd(_mm256_set1_pd(1), m);
    d.x = _mm256_mul_pd(d.x, inv_m), d.y = _mm256_mul_pd(d.y, inv_m);
    d.z = _mm256_mul_pd(d.z, inv_m);
    const __m256d len = _mm256_sqrt_pd(
        _mm256_fmadd_pd(d.x, d.x, _mm256_fmadd_pd(d.y, d.y, _mm256_mul_pd(d.z, d.z))));
    const __m256d inv_len = _mm256_div_pd(_mm256_set1_pd(1), len);
    return {_mm256_mul_pd(d.x, inv_len), _mm256_mul_pd(d.y, inv_len), _mm256_mul_pd(d.z, inv_len)};
}

// load3() of p[k … k + 3], lanes at n and beyond holding copies of p[n − 1].
Lanes3 load3_padded(const Vec3* p, size_t k, size_t n) {
    const Vec3 v[4] = {p[k], p[std::min(k + 1, n - 1)], p[std::min(k + 2, n - 1)],
                       p[std::min(k + 3, n - 1)]};
    return load3(v);
}

// view_of_prepared() of four prepared view vectors; `regular` loses the lanes along the normal.
void view_lanes(const Lanes3& o, __m256d& regular, __m256d& theta, __m256d& phi, __m256d& c,
                __m256d& s) {
    const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1);
    const __m256d two_pi = _mm256_set1_pd(2 * kPi);
    const __m256d rho = _mm256_sqrt_pd(_mm256_fmadd_pd(o.x, o.x, _mm256_mul_pd(o.y, o.y)));
    regular = _mm256_and_pd(regular, _mm256_cmp_pd(rho, zero, _CMP_GT_OQ));
    const __m256d safe_rho = _mm256_blendv_pd(one, rho, regular);
    theta = fast_atan2(safe_rho, o.z);
    phi = fast_atan2(o.y, _mm256_blendv_pd(one, o.x, regular));
    phi = _mm256_add_pd(phi, _mm256_and_pd(two_pi, _mm256_cmp_pd(phi, zero, _CMP_LT_OQ)));
    phi = _mm256_sub_pd(phi, _mm256_and_pd(two_pi, _mm256_cmp_pd(phi, two_pi, _CMP_GE_OQ)));
    const __m256d inv_rho = _mm256_div_pd(one, safe_rho);
    c = _mm256_mul_pd(o.x, inv_rho), s = _mm256_mul_pd(o.y, inv_rho);
}

// onion_of_prepared() of four prepared light vectors in the frames (c, s); `regular` loses the
// lanes at a pole.
void onion_lanes(const Lanes3& i, __m256d c, __m256d s, __m256d& regular, __m256d& alpha,
                 __m256d& u) {
    const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1);
    u = _mm256_min_pd(
        one, _mm256_max_pd(_mm256_set1_pd(-1), _mm256_fmsub_pd(c, i.y, _mm256_mul_pd(s, i.x))));
    const __m256d a = _mm256_fnmsub_pd(c, i.x, _mm256_mul_pd(s, i.y));  // −c·x − s·y
    // α is undefined at the poles (a = z = 0): the scalar path returns 0 there.
    const __m256d sign = _mm256_set1_pd(-0.0);
    regular = _mm256_and_pd(
        regular, _mm256_cmp_pd(_mm256_max_pd(_mm256_andnot_pd(sign, a), i.z), zero, _CMP_GT_OQ));
    alpha = fast_atan2(a, _mm256_blendv_pd(one, i.z, regular));
}

}  // namespace
#endif

void lookup(const MlvqGrid& grid, const Vec3* wi, const Vec3* wo, size_t n, MlvqWeights* out) {
    size_t k = 0;
#ifdef __AVX2__
    for (; k + 4 <= n; k += 4) {
        __m256d regular = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        const Lanes3 o = prepare(load3(wo + k), regular);
        const Lanes3 i = prepare(load3(wi + k), regular);
        __m256d theta, phi, c, s, alpha, u;
        view_lanes(o, regular, theta, phi, c, s);
        onion_lanes(i, c, s, regular, alpha, u);
        alignas(32) double l_alpha[4], l_u[4], l_theta[4], l_phi[4];
        _mm256_store_pd(l_alpha, alpha);
        _mm256_store_pd(l_u, u);
        _mm256_store_pd(l_theta, theta);
        _mm256_store_pd(l_phi, phi);
        const int mask = _mm256_movemask_pd(regular);
        for (int lane = 0; lane < 4; ++lane)
            out[k + lane] = (mask >> lane & 1) ? weights_of(grid, l_alpha[lane], l_u[lane],
                                                            l_theta[lane], l_phi[lane])
                                               : lookup(grid, wi[k + lane], wo[k + lane]);
    }
#endif
    for (; k < n; ++k) out[k] = lookup(grid, wi[k], wo[k]);
}

void lookup_views(const MlvqGrid& grid, const Vec3* wo, size_t n, ViewLookup* out) {
    const AxisScales scales(grid);
    // A view the vector lanes leave out (not a direction, along the normal): the scalar angles.
    auto scalar = [&](const Vec3& d, ViewLookup& v) {
        double theta = 0, phi = 0, c = 1, s = 0;
        view_of_prepared(prepare(d), theta, phi, c, s, true);
        v.weights = {};
        view_axes_scaled(grid, scales, theta, phi, v.weights);
        v.frame = OnionFrame(c, s);
    };
#ifdef __AVX2__
    for (size_t k = 0; k < n; k += 4) {
        __m256d regular = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        __m256d theta, phi, c, s;
        view_lanes(prepare(load3_padded(wo, k, n), regular), regular, theta, phi, c, s);
        alignas(32) double l_theta[4], l_phi[4], l_c[4], l_s[4];
        _mm256_store_pd(l_theta, theta);
        _mm256_store_pd(l_phi, phi);
        _mm256_store_pd(l_c, c);
        _mm256_store_pd(l_s, s);
        const int mask = _mm256_movemask_pd(regular);
        for (size_t lane = 0; lane < 4 && k + lane < n; ++lane) {
            ViewLookup& v = out[k + lane];
            if (mask >> lane & 1) {
                v.weights = {};
                view_axes_scaled(grid, scales, l_theta[lane], l_phi[lane], v.weights);
                v.frame = OnionFrame(l_c[lane], l_s[lane]);
            } else {
                scalar(wo[k + lane], v);
            }
        }
    }
#else
    for (size_t k = 0; k < n; ++k) scalar(wo[k], out[k]);
#endif
}

void lookup_lights(const MlvqGrid& grid, const Vec3* wi, const ViewLookup* view, size_t n,
                   MlvqWeights* out) {
    const AxisScales scales(grid);
    // OnionFrame(c, s) holds e_β = (−s, c, 0): c and s come back exactly.
    auto cos_sin = [&](size_t k, double& c, double& s) {
        c = view[k].frame.e_beta.y, s = -view[k].frame.e_beta.x;
    };
#ifdef __AVX2__
    for (size_t k = 0; k < n; k += 4) {
        alignas(32) double l_c[4], l_s[4];
        for (size_t lane = 0; lane < 4; ++lane)
            cos_sin(std::min(k + lane, n - 1), l_c[lane], l_s[lane]);
        __m256d regular = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        __m256d alpha, u;
        onion_lanes(prepare(load3_padded(wi, k, n), regular), _mm256_load_pd(l_c),
                    _mm256_load_pd(l_s), regular, alpha, u);
        alignas(32) double l_alpha[4], l_u[4];
        _mm256_store_pd(l_alpha, alpha);
        _mm256_store_pd(l_u, u);
        const int mask = _mm256_movemask_pd(regular);
        for (size_t lane = 0; lane < 4 && k + lane < n; ++lane) {
            if (!(mask >> lane & 1))  // not a direction, or at a pole of the frame
                onion_of_prepared(prepare(wi[k + lane]), l_c[lane], l_s[lane], l_alpha[lane],
                                  l_u[lane], true);
            light_axes_scaled(grid, scales, l_alpha[lane], l_u[lane], out[k + lane]);
        }
    }
#else
    for (size_t k = 0; k < n; ++k) {
        double c, s, alpha, u;
        cos_sin(k, c, s);
        onion_of_prepared(prepare(wi[k]), c, s, alpha, u, true);
        light_axes_scaled(grid, scales, alpha, u, out[k]);
    }
#endif
}

float reconstruct(const MlvqGrid& grid, const MlvqWeights& w, const float* values) {
    float sum = 0;
    for (int p = 0; p < 2; ++p)
        for (int t = 0; t < 2; ++t)
            for (int a = 0; a < 2; ++a)
                for (int b = 0; b < 2; ++b)
                    sum += w.weight(a, b, t, p) * values[w.sample(grid, a, b, t, p)];
    return sum;
}

// ---- reading texels ----------------------------------------------------------------------------

SourceTexels::SourceTexels(int views, int lights, int64_t texels)
    : m_views(views), m_lights(lights), m_texels(texels) {
    if (views < 0 || lights < 0 || texels < 0)
        fail("{}: texels of {} views x {} lights x {} texels", kGridName, views, lights, texels);
    m_values.assign(size_t(bytes(views, lights, texels) / int64_t(sizeof(float))), 0.0f);
}

SourceTexels read_rows(const BtfSource& source, int y0, int rows, Progress& progress) {
    const int width = source.width(), height = source.height();
    if (rows < 1 || y0 < 0 || y0 > height - rows)
        fail("{}: texel rows {} to {} are outside the image's {} rows", source_name(source), y0,
             int64_t(y0) + rows - 1, height);
    SourceTexels out(source.num_views(), source.num_lights(), int64_t(width) * rows);
    const int64_t texels = out.texels();
    for (int v = 0; v < out.views(); ++v) {
        progress.poll();
        parallel_for(0, out.lights(), [&](int64_t light) {
            thread_local Image image;
            source.read_image(v, static_cast<int>(light), image);
            if (image.width() != width || image.height() != height || image.channels() < 3)
                fail("{}: image (view {}, light {}) is {}x{}x{}, expected {}x{}x3",
                     source_name(source), v, light, image.width(), image.height(), image.channels(),
                     width, height);
            const int channels = image.channels();
            const float* px = image.data() + int64_t(y0) * width * channels;
            const int p = v * out.lights() + static_cast<int>(light);
            for (int64_t t0 = 0; t0 < texels; t0 += SourceTexels::kTile) {
                float* r = out.data() + out.offset(p, 0, t0);
                const int n = static_cast<int>(std::min<int64_t>(SourceTexels::kTile, texels - t0));
                for (int q = 0; q < n; ++q) {
                    const float* x = px + (t0 + q) * channels;
                    r[q] = x[0];
                    r[SourceTexels::kTile + q] = x[1];
                    r[2 * SourceTexels::kTile + q] = x[2];
                }
            }
        });
        progress.advance(out.lights());
    }
    return out;
}

// ---- resampling --------------------------------------------------------------------------------

Resampler::Resampler(const MlvqGrid& grid, const Sampling& sampling)
    : m_grid(grid), m_views(sampling.num_views()), m_lights(sampling.num_lights()) {
    m_grid.validate();
    if (m_views < 1 || m_lights < 1) fail("{}: resampling needs views and lights", kGridName);
    if (int64_t(m_views) * m_lights > int64_t(INT32_MAX))
        fail("{}: {} views x {} lights are too many images", kGridName, m_views, m_lights);
    const AngularInterpolator view_interp(sampling.views);
    const AngularInterpolator light_interp(sampling.lights);
    const MlvqGrid& g = m_grid;

    // Light weights depend on (φv, α, β) only, view weights on (φv, θv) only.
    std::vector<AngularWeights> light(size_t(g.n_phi_v) * g.light_samples());
    std::vector<AngularWeights> view(size_t(g.n_phi_v) * g.n_theta_v);
    for (int m = 0; m < g.n_phi_v; ++m) {
        for (int k = 0; k < g.n_theta_v; ++k)
            view[size_t(m) * g.n_theta_v + k] =
                view_interp.weights(Direction{g.theta_v(k), g.phi_v(m)});
        for (int i = 0; i < g.n_alpha; ++i)
            for (int j = 0; j < g.n_beta; ++j)
                light[(size_t(m) * g.n_alpha + i) * g.n_beta + j] = light_interp.weights(
                    direction_from_onion_u(g.alpha(i), g.sin_beta(j), g.phi_v(m)));
    }

    m_offsets.reserve(size_t(g.samples()) + 1);
    m_offsets.push_back(0);
    m_terms.reserve(size_t(g.samples()) * 4);
    std::vector<std::pair<int32_t, double>> terms;
    for (int m = 0; m < g.n_phi_v; ++m)
        for (int k = 0; k < g.n_theta_v; ++k)
            for (int i = 0; i < g.n_alpha; ++i)
                for (int j = 0; j < g.n_beta; ++j) {
                    const AngularWeights& vw = view[size_t(m) * g.n_theta_v + k];
                    const AngularWeights& lw = light[(size_t(m) * g.n_alpha + i) * g.n_beta + j];
                    terms.clear();
                    double total = 0;
                    for (int a = 0; a < vw.count; ++a)
                        for (int b = 0; b < lw.count; ++b)
                            total += double(vw.weight[a]) * lw.weight[b];
                    // Terms below float resolution (a sample next to a source direction) are
                    // dropped: they cannot change a float value, and cost a gather each.
                    double sum = 0;
                    for (int a = 0; a < vw.count; ++a)
                        for (int b = 0; b < lw.count; ++b) {
                            const double w = double(vw.weight[a]) * lw.weight[b];
                            if (!(w > kNegligible * total)) continue;
                            terms.emplace_back(vw.index[a] * m_lights + lw.index[b], w);
                            sum += w;
                        }
                    if (!(sum > 0))
                        fail(
                            "{}: the angular interpolator gave no weight to grid sample (phi_v "
                            "{}, theta_v {}, alpha {}, beta {})",
                            kGridName, m, k, i, j);
                    std::sort(terms.begin(), terms.end());
                    for (const auto& [image, w] : terms)
                        m_terms.push_back({image, static_cast<float>(w / sum)});
                    m_offsets.push_back(static_cast<int64_t>(m_terms.size()));
                }
}

void Resampler::gather_tile(const SourceTexels& raw, int64_t tile, float* out) const {
    constexpr int kTile = SourceTexels::kTile;
    static_assert(kTile == kLanes);
    const int64_t n = samples();
    const float* base = raw.data() + raw.offset(0, 0, tile * kTile);
    const Term* terms = m_terms.data();
    constexpr int64_t kAhead = 6;  // samples whose source values are prefetched in advance
    for (int64_t s = 0; s < n; ++s) {
        if (s + kAhead < n)
            for (int64_t e = m_offsets[s + kAhead]; e < m_offsets[s + kAhead + 1]; ++e) {
                const float* p = base + int64_t(terms[e].image) * 3 * kTile;
                __builtin_prefetch(p);
                __builtin_prefetch(p + 2 * kTile);
            }
        Lanes r = {}, g = {}, b = {};
        for (int64_t e = m_offsets[s]; e < m_offsets[s + 1]; ++e) {
            const float* p = base + int64_t(terms[e].image) * 3 * kTile;
            const float w = terms[e].weight;
            r += w * load(p);
            g += w * load(p + kTile);
            b += w * load(p + 2 * kTile);
        }
        for (int t = 0; t < kTile; ++t) {
            float* o = out + int64_t(t) * 3 * n + s;
            o[0] = r[t];
            o[n] = g[t];
            o[2 * n] = b[t];
        }
    }
}

void Resampler::gather_texel(const SourceTexels& raw, int64_t texel, float* out) const {
    constexpr int kTile = SourceTexels::kTile;
    const int64_t n = samples();
    const float* base = raw.data() + raw.offset(0, 0, texel);
    for (int64_t s = 0; s < n; ++s) {
        float acc[3] = {0, 0, 0};
        for (int64_t e = m_offsets[s]; e < m_offsets[s + 1]; ++e) {
            const float* r = base + int64_t(m_terms[e].image) * 3 * kTile;
            const float w = m_terms[e].weight;
            for (int c = 0; c < 3; ++c) acc[c] += w * r[c * kTile];
        }
        for (int c = 0; c < 3; ++c) out[c * n + s] = acc[c];
    }
}

void Resampler::check(const SourceTexels& raw) const {
    if (raw.views() != m_views || raw.lights() != m_lights)
        fail("{}: texels of {} views x {} lights given to a resampler of {} x {}", kGridName,
             raw.views(), raw.lights(), m_views, m_lights);
}

void Resampler::resample(const SourceTexels& raw, int64_t first, int64_t count, float* out) const {
    check(raw);
    if (first < 0 || count < 0 || first > raw.texels() - count)
        fail("{}: texels {} to {} are outside the {} given", kGridName, first, first + count - 1,
             raw.texels());
    constexpr int kTile = SourceTexels::kTile;
    const int64_t stride = 3 * samples(), end = first + count;
    int64_t t = first;
    while (t < end) {
        if (t % kTile == 0 && t + kTile <= end) {
            gather_tile(raw, t / kTile, out + (t - first) * stride);
            t += kTile;
        } else {
            gather_texel(raw, t, out + (t - first) * stride);
            ++t;
        }
    }
}

std::vector<float> Resampler::resample(const SourceTexels& raw) const {
    std::vector<float> out(size_t(raw.texels()) * 3 * size_t(samples()));
    resample(raw, out);
    return out;
}

void Resampler::resample(const SourceTexels& raw, std::span<float> out) const {
    check(raw);
    if (int64_t(out.size()) != raw.texels() * 3 * samples())
        fail("{}: {} output values for {} texels of {} samples in 3 channels", kGridName,
             out.size(), raw.texels(), samples());
    constexpr int64_t kChunk = 4 * SourceTexels::kTile;
    parallel_chunks(0, raw.texels(), kChunk, [&](int64_t b, int64_t e) {
        resample(raw, b, e - b, out.data() + b * 3 * samples());
    });
}

}  // namespace btf::mlvq
