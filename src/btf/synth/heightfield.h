// SPDX-License-Identifier: MIT
#pragma once
/// Periodic scalar fields, tileable procedural noise and the ray queries on a height field that
/// give the synthetic BTFs their hard effects: cast shadows toward a light, the surface point a
/// viewer sees through a texel (masking and parallax), and the sky visibility that drives the
/// inter-reflection term.
///
/// Everything here is periodic with the field's size (tileable in u and v) and deterministic:
/// noise is a pure function of its coordinates and seed, and every ray query computes each texel
/// independently, so results do not depend on the number of threads.

#include <cstdint>
#include <vector>

#include "btf/core/math.h"

namespace btf::synth {

// ---- hashing (counter-based: the same inputs give the same bits on every platform) ----

/// The SplitMix64 finalizer: a bijective 64-bit mix.
uint64_t mix64(uint64_t x);
/// Hash of a seed and up to three integer coordinates.
uint64_t hash(uint64_t seed, int64_t a, int64_t b = 0, int64_t c = 0);
/// hash() mapped to a double uniform in [0, 1).
double hash_unit(uint64_t seed, int64_t a, int64_t b = 0, int64_t c = 0);

/// A square scalar field of size × size samples at texel centres, periodic in both directions.
class Field {
  public:
    Field() = default;
    explicit Field(int size, float fill = 0.0f);

    int size() const { return m_size; }
    bool empty() const { return m_values.empty(); }
    float& operator()(int x, int y) { return m_values[size_t(y) * m_size + x]; }
    float operator()(int x, int y) const { return m_values[size_t(y) * m_size + x]; }
    /// Value at any integer texel, wrapped into the period.
    float wrapped(int x, int y) const;
    /// Bilinear interpolation at continuous texel coordinates (texel centres at integer + 0.5),
    /// wrapped into the period.
    float bilinear(double x, double y) const;

    float min() const;
    float max() const;
    double mean() const;
    std::vector<float>& values() { return m_values; }
    const std::vector<float>& values() const { return m_values; }

  private:
    int m_size = 0;
    std::vector<float> m_values;
};

/// Index i wrapped into [0, n).
inline int wrap_index(int i, int n) {
    i %= n;
    return i < 0 ? i + n : i;
}

// ---- tileable procedural noise on the unit square (u, v in [0, 1), period 1) ----

/// Gradient (Perlin) noise with `px` × `py` lattice cells over the unit square, so it tiles with
/// period 1 in u and v; roughly in [-1, 1], zero at lattice points.
double noise(double u, double v, int px, int py, uint64_t seed);
/// Fractal sum of noise(): octave k has (px, py)·2^k cells and amplitude gain^k; normalized so
/// the amplitudes sum to 1.
double fbm(double u, double v, int px, int py, int octaves, double gain, uint64_t seed);

/// Worley (cellular) noise: one jittered feature point per cell of a cells × cells grid.
struct Cells {
    double f1 = 0, f2 = 0;  ///< distance to the nearest and second-nearest point, in cell units
    int ix = 0, iy = 0;     ///< cell of the nearest point (wrapped into [0, cells))
    uint64_t id = 0;        ///< hash of the nearest point's cell: a random value per cell
};
Cells worley(double u, double v, int cells, double jitter, uint64_t seed);

// ---- filters ----

/// Periodic box blur of radius r (window 2r + 1), repeated `passes` times (≈ Gaussian).
Field blur(const Field& field, int radius, int passes = 2);

// ---- ray queries on a height field (heights in texel units) ----

/// Visibility of a light in direction `light` (unit vector, z > 0) from each texel centre at its
/// height: 1 lit, 0 in a cast shadow, soft in between. The light is a disc of angular diameter
/// `light_size` (radians), so shadows have penumbrae. Writes size² values, row-major.
void light_visibility(const Field& height, const Vec3& light, double light_size, float* out);

/// For each output texel, the surface point a viewer in direction `view` sees through it:
/// the first intersection of the view ray through (texel centre, `reference` height) with the
/// height field, as continuous texel coordinates (x, y). For the zenith view this is the texel
/// centre itself. Writes size² pairs, row-major, into `hit_x` and `hit_y`.
void view_hits(const Field& height, const Vec3& view, double reference, float* hit_x, float* hit_y);

/// Cosine-weighted fraction of the hemisphere above each texel that is open sky (not blocked by
/// the height field), from the horizon angle in `azimuths` directions. 1 on a flat surface.
Field sky_visibility(const Field& height, int azimuths);

}  // namespace btf::synth
