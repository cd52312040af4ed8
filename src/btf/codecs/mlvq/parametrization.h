// SPDX-License-Identifier: MIT
#pragma once
/// The angular parametrization of the multi-level vector quantization codec `mlvq` (Havran, Filip,
/// Myszkowski 2010, §4.1, Fig. 4–6): the regular 4-D grid F_x(α, β, θv, φv) on which every
/// texel's apparent BRDF is stored, the mapping between (ωi, ωo) and grid coordinates, the
/// continuous (multilinear) lookup used by evaluation, and the resampling of any measured sampling
/// onto the grid.
///
/// Frames and angles. Directions are in btfkit's local frame (z = normal, φ from the tangent +u
/// toward +v, θ from the normal; core/direction.h). The view ωo = (θv, φv) is used as is. The light
/// ωi is expressed in the "onion slice" frame of the view azimuth φv (the paper's Fig. 4):
///
///     e_β = (−sin φv, cos φv, 0)   the diameter A–B, perpendicular to the view azimuth
///     e_α = (−cos φv, −sin φv, 0)  horizontal, pointing away from the viewer (mirror side)
///     n   = (0, 0, 1)              the pole E
///     ωi  = sin β · e_β + sin α cos β · e_α + cos α cos β · n,     α, β ∈ [−π/2, π/2]   (eq. 2)
///
/// (e_β, e_α, n) is right-handed. Inversely, with Δ = φi − φv,
///
///     sin β = ωi · e_β = sin θi sin Δ,
///     α     = atan2(ωi · e_α, ωi · n) = atan2(−sin θi cos Δ, cos θi),
///
/// i.e. |α| = arccos(cos θi / cos β), negative on the viewer's side (cos Δ > 0). A slice (fixed α)
/// is the half great circle from the pole A (β = −π/2, ωi = −e_β) over the top to B (β = +π/2,
/// ωi = +e_β); A and B lie on the horizon, so every slice shares both end points; α = ±π/2 are the
/// two slices on the horizon, α = 0 passes through the normal.
///
/// Orientation (a decision; the paper is self-contradictory here). Eq. 3 of the paper reads
/// β = arcsin(sin θi cos(φi − φv)), which puts A and B in the plane of incidence. Its text says
/// the opposite three times: the line A–B "is always perpendicular to the azimuth of viewing
/// direction", the ideal mirror reflection lies in the plane β = 0, and the middle of every slice
/// is sampled densely *because* that is where reflectance changes steeply. btfkit follows the
/// text: with A–B perpendicular to the view azimuth the plane of incidence is β = 0, the mirror
/// direction of (θv, φv) is (α, β) = (θv, 0) and the view itself (retro-reflection) is (−θv, 0),
/// so the specular peak of every view lies at the densely sampled middle of a slice. This is eq. 3
/// with φv replaced by φv + π/2 (cos → sin) and the sign of α made explicit.
///
/// Sample positions (MlvqGrid; every axis is uniform in its interpolation coordinate, so the
/// lookup is linear in the fractional sample index along each axis):
///
///     α_i  = −π/2 + π · i / (nα − 1),              i = 0 … nα − 1   (slices, both horizon slices
///                                                                    included: uniform placement
///                                                                    over the closed range)
///     u_j  = sin β_j = −1 + 2 · j / (nβ − 1),      j = 0 … nβ − 1   (uniform in sin β)
///     θv_k = (π/2) · k / (nθv − 1),                k = 0 … nθv − 1
///     φv_m = 2π · m / nφv,                         m = 0 … nφv − 1  (periodic, 2π not repeated)
///
/// β: "uniformly in cos β" (§4.1, Fig. 5) means a sample density ∝ cos β along the slice, i.e.
/// uniform in ∫cos β dβ = sin β: the samples' projections onto the diameter A–B are equidistant,
/// dense in the middle of the slice and sparse near A and B, as Fig. 5(b) shows. Since the
/// solid-angle element of eq. 2 is dω = cos β dα dβ = dα du, (α, u = sin β) is an equal-area
/// parametrization: the grid cells of the light hemisphere all have the same solid angle.
/// The poles: j = 0 and j = nβ − 1 are A and B, one direction each for all nα slices. Every
/// slice stores a value there (the grid is nα × nβ per view, 11 · 11 · 7 · 16 = 13552 samples at
/// the paper's default), resampling writes the same value into all of them, and hemisphere sums
/// count each pole once: light_weight() gives the pole row the solid angle π · Δu / 2 of the cap
/// that the pole stands for, split over its nα copies.
///
/// θv: the regular grid spans the whole hemisphere, θv = 0 (the normal) and θv = 90° (the horizon)
/// included, independently of the source's sampling. Why: (1) the grid is then the same for every
/// material, which code-books shared between materials (§5.1) require; (2) every view has grid
/// samples on both sides, so the lookup never clamps — beyond the source's outermost view ring
/// the resampled values are the AngularInterpolator's projection onto that ring, exactly what
/// every other btfkit codec returns there; (3) with the default nθv = 7 the step is 15°, which
/// lands on the measured rings 0°, 15°, …, 75° of UBO2003 (and on 0°, 30°, 45°, 60°, 75° of the
/// UBO2014 dome), so resampling those views does not blur across rings; (4) θv = 0 is a measured
/// view of both databases. At θv = 0 the nφv samples hold the normal view's apparent BRDF in nφv
/// rotated onion frames (the frame follows φv even where φv is undefined).
///
/// nφv = 1 is allowed (an isotropic material, as the paper's MERL experiment in §6): the function
/// then does not depend on the view azimuth, only on the light relative to it.
///
/// Lookup (Fig. 6). For (ωi, ωo) the coordinates are θv, φv of ωo (φv = 0 when ωo is along the
/// normal) and α, β of ωi in the onion frame of that φv; along each axis the two neighbouring
/// samples get the linear weights of the fractional index (φv wraps), and the reconstruction is
/// the multilinear blend of the 2 × 2 × 2 × 2 samples. Along β it is linear in u = sin β, not in
/// β (equal-area, and what makes the inverse CDF of §5.2 exact for piecewise-linear data).
/// The reconstruction is continuous in (ωi, ωo) everywhere except at ωo = normal: near the light
/// poles the α weights change fast but their samples agree at the pole (the β weight of the pole
/// row goes to 1), across φv = 2π the index wraps; at the view normal the onion frame's azimuth
/// is undefined, so the limit depends on the azimuth of approach: it blends the normal view's
/// apparent BRDF with its light directions rotated by at most one φv step (22.5° at the default).
/// This is inherent to a light frame aligned with the view azimuth (the paper's Fig. 6 has the
/// same property).
/// Queries need not be unit vectors; as in AngularInterpolator, directions below the horizon are
/// clamped onto it at their azimuth, and a vector without such a direction (zero, straight down,
/// not finite) is +x on the horizon.
///
/// Resampling (§4.1, last paragraph). The paper interpolated the measured (ωi, ωo) samples with
/// radial basis functions; btfkit uses the shared barycentric AngularInterpolator on the source's
/// view set and on its light set (the light direction of a grid sample is taken to the global
/// local frame first), so each grid value is a convex blend of ≤ 3 views × ≤ 3 lights of the
/// source. Resampler precomputes these ≤ 9 (image, weight) pairs for every grid sample once; a
/// batch of texels is then a sparse gather from their raw values (SourceTexels), read from the
/// source view by view, all lights of a view in parallel.
///
/// Value layout of F_x (one texel, one channel): sample index
///     s = ((m · nθv + k) · nα + i) · nβ + j     (φv slowest, β fastest: a β slice is contiguous,
///                                               a (α, β) slice is one 2-D light function)
/// and a texel's three channels follow each other: value (texel t, channel c, sample s) at
/// out[(t · 3 + c) · samples + s].

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "btf/core/direction.h"
#include "btf/core/math.h"
#include "btf/io/source.h"
#include "btf/util/progress.h"

namespace btf::mlvq {

/// The discretization of F_x(α, β, θv, φv). Defaults are the paper's (§6).
struct MlvqGrid {
    int n_alpha = 11;   ///< slices across the light hemisphere (≥ 3)
    int n_beta = 11;    ///< samples along a slice, poles included (≥ 3)
    int n_theta_v = 7;  ///< view elevations 0 … 90° (≥ 2)
    int n_phi_v = 16;   ///< view azimuths (1 = isotropic, otherwise ≥ 3)

    /// Largest count accepted per axis, and for the whole grid (samples()).
    static constexpr int kMaxAxis = 1024;
    static constexpr int64_t kMaxSamples = int64_t(1) << 26;

    /// Throws btf::Error naming the parameter when an axis is out of range (see the members) or
    /// the grid has more than kMaxSamples samples.
    void validate() const;

    /// nφv · nθv · nα · nβ
    int64_t samples() const { return int64_t(n_phi_v) * n_theta_v * n_alpha * n_beta; }
    /// nα · nβ: one light function (view fixed).
    int light_samples() const { return n_alpha * n_beta; }
    /// Sample index of (φv m, θv k, α i, β j).
    int64_t index(int m, int k, int i, int j) const {
        return ((int64_t(m) * n_theta_v + k) * n_alpha + i) * n_beta + j;
    }

    /// α_i = −π/2 + π i / (nα − 1)
    double alpha(int i) const;
    /// u_j = sin β_j = −1 + 2 j / (nβ − 1) (exactly ±1 at the poles)
    double sin_beta(int j) const;
    /// β_j = arcsin(u_j)
    double beta(int j) const;
    /// θv_k = (π/2) k / (nθv − 1)
    double theta_v(int k) const;
    /// φv_m = 2π m / nφv
    double phi_v(int m) const;

    /// Solid angle attributed to light sample (i, j) when a light function is summed over the
    /// hemisphere: the trapezoid weight of the equal-area coordinates (α, u),
    /// Δα · Δu · (½ at i = 0, nα − 1) · (½ at j = 0, nβ − 1). Σ over (i, j) = 2π, and
    /// Σ_(i,j) light_weight · f(i, j) = ∫ f̂ dω exactly for the lookup's reconstruction f̂. A pole
    /// row (j = 0 or nβ − 1) sums to π Δu / 2, the area of the polar cap: the pole counts once.
    double light_weight(int i, int j) const;
};

/// Light direction in onion-slice angles (radians).
struct OnionAngles {
    double alpha = 0;  ///< slice, [−π/2, π/2]
    double beta = 0;   ///< position along the slice, [−π/2, π/2]
};

/// The onion frame (e_β, e_α, n) of view azimuth φv, as unit vectors in the local frame.
struct OnionFrame {
    Vec3 e_beta{-0.0, 1, 0}, e_alpha{-1, -0.0, 0}, n{0, 0, 1};  ///< as OnionFrame(0.0) has them
    /// The frame of φv = 0, without a call of sin and cos (lookup arrays and sample states
    /// construct one each: libm's sincos there took 4 % of a stochastic sample's time).
    OnionFrame() = default;
    explicit OnionFrame(double phi_v);
    /// From cos φv and sin φv.
    OnionFrame(double cos_phi_v, double sin_phi_v)
        : e_beta{-sin_phi_v, cos_phi_v, 0}, e_alpha{-cos_phi_v, -sin_phi_v, 0} {}
};

/// ωi (any non-zero vector; clamped onto the horizon when below it) → (α, β) in the frame of φv.
/// At the poles A, B α is undefined and returned as 0; a vector without a direction on the upper
/// hemisphere (zero, straight down, not finite) is +x on the horizon.
OnionAngles onion_from_direction(const Vec3& wi, double phi_v);
/// (α, β) in the frame of φv → unit ωi (eq. 2).
Vec3 direction_from_onion(const OnionAngles& angles, double phi_v);
/// The same with u = sin β given instead of β (exact at the poles: cos β = √(1 − u²)).
Vec3 direction_from_onion_u(double alpha, double sin_beta, double phi_v);
/// The same in a frame built beforehand.
Vec3 direction_from_onion_u(double alpha, double sin_beta, const OnionFrame& frame);
/// sin α and cos α, within 4e-16 of libm's for |α| ≤ π/2 (the range of the slices: a polynomial
/// in place of libm's sincos, which took ~4 % of a stochastic sample's time in a profile);
/// libm's beyond.
void sin_cos_half_pi(double alpha, double& sin_alpha, double& cos_alpha);

/// A (light, view) pair in grid coordinates (radians).
struct MlvqCoordinates {
    double alpha = 0, beta = 0;     ///< light, in the onion frame of phi_v
    double theta_v = 0, phi_v = 0;  ///< view; phi_v in [0, 2π), 0 for a view along the normal
};
/// (ωi, ωo) → grid coordinates (eq. 1 and the mapping above).
MlvqCoordinates to_mlvq(const Vec3& wi, const Vec3& wo);
/// Grid coordinates → unit (ωi, ωo).
void from_mlvq(const MlvqCoordinates& c, Vec3& wi, Vec3& wo);

/// The two neighbouring samples along one axis and their linear weights (sum 1; at a sample
/// position the other weight is 0). index[1] = index[0] + 1, or wrapped along φv (both 0 when
/// nφv = 1).
struct AxisWeights {
    std::array<int, 2> index{};
    std::array<float, 2> weight{};
};

/// The 2 × 2 × 2 × 2 neighbouring grid samples of a query and their separable weights.
struct MlvqWeights {
    AxisWeights alpha, beta, theta_v, phi_v;
    /// Sample index and weight of corner (a, b, t, p) ∈ {0, 1}⁴ of the 16.
    int64_t sample(const MlvqGrid& grid, int a, int b, int t, int p) const {
        return grid.index(phi_v.index[p], theta_v.index[t], alpha.index[a], beta.index[b]);
    }
    float weight(int a, int b, int t, int p) const {
        return alpha.weight[a] * beta.weight[b] * theta_v.weight[t] * phi_v.weight[p];
    }
};

/// Weights along each axis for continuous grid coordinates (clamped into range; φv wraps). The
/// lookup functions do not check the grid (they are the evaluator's inner loop): validate() it
/// once beforehand.
MlvqWeights lookup(const MlvqGrid& grid, const MlvqCoordinates& c);
/// lookup(grid, to_mlvq(wi, wo)), with the angles computed by an atan2 accurate to 7e-9 rad
/// instead of libm's (the evaluator's inner loop; the weights differ by less than 1e-8).
MlvqWeights lookup(const MlvqGrid& grid, const Vec3& wi, const Vec3& wo);
/// The view part of a lookup: θv and φv weights of ωo (α and β weights are left at 0), and the
/// onion frame of its azimuth (φv = 0 for a view along the normal), as lookup() has them.
struct ViewLookup {
    MlvqWeights weights;
    OnionFrame frame;  ///< φv = 0 until looked up
};
ViewLookup lookup_view(const MlvqGrid& grid, const Vec3& wo);
/// lookup(grid, wi[k], wo[k]) for k < n, four at a time with AVX2 where the build has it (the
/// scalar path for directions that need its conventions: zero, not finite, a view along the
/// normal, a light at a pole); the weights agree with the scalar ones to within 1e-6.
void lookup(const MlvqGrid& grid, const Vec3* wi, const Vec3* wo, size_t n, MlvqWeights* out);
/// lookup_view(grid, wo[k]) for k < n, four at a time with AVX2 where the build has it (weights
/// and frames within 1e-6 of the scalar ones). Unlike lookup() above, every direction goes
/// through the same code, those of a last partial group too (its free lanes hold copies of its
/// last direction): a direction's lookup does not depend on n or on its place, so one query
/// (n = 1) and a batch agree bit for bit, which the stochastic filter's batches rely on.
void lookup_views(const MlvqGrid& grid, const Vec3* wo, size_t n, ViewLookup* out);
/// The light part of lookup(grid, wi[k], ωo) for k < n, ωo's onion frame given by view[k]
/// (lookup_views()): sets out[k].alpha and .beta and leaves the rest of out[k] as it is. One
/// atan2 per light where lookup() takes three; independent of n and of the place as
/// lookup_views() is.
void lookup_lights(const MlvqGrid& grid, const Vec3* wi, const ViewLookup* view, size_t n,
                   MlvqWeights* out);
/// The multilinear reconstruction Σ weight · values[sample] over the 16 corners; `values` holds
/// grid.samples() values of one channel.
float reconstruct(const MlvqGrid& grid, const MlvqWeights& w, const float* values);

/// Raw RGB samples of a set of texels for every (view, light) image of a source: the input of
/// the resampling gather. Image p = view · lights + light; texels are numbered within the set.
///
/// Layout: texels in tiles of kTile; a tile holds all images, an image its three channels, a
/// channel the kTile texels of the tile (the last tile is padded with zeros):
///     values[((tile · images + p) · 3 + channel) · kTile + texel % kTile],  tile = texel / kTile
/// so that the gather over one tile reads one contiguous block (81 × 81 images: 0.6 MiB) in
/// which each source view's lights are adjacent, instead of one cache line per image and
/// channel scattered over the whole set.
class SourceTexels {
  public:
    static constexpr int kTile = 8;

    SourceTexels() = default;
    /// Zeros for `texels` texels of views × lights images.
    SourceTexels(int views, int lights, int64_t texels);

    int views() const { return m_views; }
    int lights() const { return m_lights; }
    int images() const { return m_views * m_lights; }
    int64_t texels() const { return m_texels; }
    int64_t tiles() const { return (m_texels + kTile - 1) / kTile; }

    int64_t offset(int image, int channel, int64_t texel) const {
        return ((texel / kTile * images() + image) * 3 + channel) * kTile + texel % kTile;
    }
    float value(int view, int light, int channel, int64_t texel) const {
        return m_values[offset(view * m_lights + light, channel, texel)];
    }
    float& at(int view, int light, int channel, int64_t texel) {
        return m_values[offset(view * m_lights + light, channel, texel)];
    }
    const float* data() const { return m_values.data(); }
    float* data() { return m_values.data(); }
    /// Bytes held (padding included).
    int64_t bytes() const { return int64_t(m_values.size() * sizeof(float)); }
    /// Bytes that `texels` texels of `views` × `lights` images take.
    static int64_t bytes(int views, int lights, int64_t texels) {
        return (texels + kTile - 1) / kTile * kTile * views * lights * 3 * int64_t(sizeof(float));
    }

  private:
    int m_views = 0, m_lights = 0;
    int64_t m_texels = 0;
    std::vector<float> m_values;
};

/// Reads texel rows [y0, y0 + rows) of every image of `source` (texel = (y − y0) · width + x),
/// view by view with the lights of a view in parallel, calling progress.advance(lights) after
/// each view (the caller begins the stage; each call reads every image of the source once).
/// Throws btf::Error naming the source when the rows are outside the image.
SourceTexels read_rows(const BtfSource& source, int y0, int rows,
                       Progress& progress = Progress::none());

/// The resampling table of one (grid, source sampling) pair and the gather that applies it.
class Resampler {
  public:
    /// One term of a grid sample's value: weight · (image `image`, same texel, same channel).
    struct Term {
        int32_t image = 0;  ///< view · lights + light of the source
        float weight = 0;
    };

    /// Builds the table: for every grid sample the view weights of AngularInterpolator on
    /// sampling.views at (θv, φv) times the light weights on sampling.lights at the sample's
    /// light direction in the local frame. Throws btf::Error for an invalid grid or sampling.
    Resampler(const MlvqGrid& grid, const Sampling& sampling);

    const MlvqGrid& grid() const { return m_grid; }
    int64_t samples() const { return m_grid.samples(); }
    int views() const { return m_views; }
    int lights() const { return m_lights; }
    /// The ≤ 9 terms of grid sample s (weights > 0, sum 1, in increasing image order; terms
    /// below 10⁻⁷ of the sample's total weight, which cannot change a float value, are left out).
    /// A grid sample at a measured (view, light) pair has the one term of that image.
    std::span<const Term> terms(int64_t s) const {
        return {m_terms.data() + m_offsets[s], m_terms.data() + m_offsets[s + 1]};
    }

    /// F_x of texels [first, first + count) of `raw` into out[(t · 3 + c) · samples() + s],
    /// t = 0 … count − 1 (single-threaded; whole tiles of raw are gathered 8 texels at a time,
    /// texels of partial tiles one by one). Throws btf::Error when raw does not match the
    /// sampling or the range is outside it.
    void resample(const SourceTexels& raw, int64_t first, int64_t count, float* out) const;
    /// F_x of every texel of `raw` into `out` (raw.texels() · 3 · samples() values in the layout
    /// above), in parallel over tiles of texels; the result does not depend on the number of
    /// threads. Throws btf::Error on a size mismatch.
    void resample(const SourceTexels& raw, std::span<float> out) const;
    /// The same into a new vector.
    std::vector<float> resample(const SourceTexels& raw) const;

  private:
    void check(const SourceTexels& raw) const;
    void gather_tile(const SourceTexels& raw, int64_t tile, float* out) const;
    void gather_texel(const SourceTexels& raw, int64_t texel, float* out) const;

    MlvqGrid m_grid;
    int m_views = 0, m_lights = 0;
    std::vector<int64_t> m_offsets;  // samples() + 1
    std::vector<Term> m_terms;
};

}  // namespace btf::mlvq
