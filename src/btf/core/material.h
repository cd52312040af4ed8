#pragma once
/// Material: random-access evaluation of a BTF at any surface position and any pair of
/// directions. Implemented by every codec's decoder and by the UBO2014 factorized-file reader.

#include <span>

#include "btf/core/direction.h"
#include "btf/core/math.h"

namespace btf {

/// Texture coordinates: u across image columns, v across rows, both in [0, 1) and wrapping;
/// (0, 0) is the corner of texel (0, 0), the first pixel of the first image row.
struct Uv {
    double u = 0, v = 0;
};

/// One query of a batched evaluation.
struct Query {
    Uv uv;
    Vec3 wi, wo;  ///< light and view direction
};

class Material {
  public:
    virtual ~Material() = default;

    /// Spatial resolution of the material's textures.
    virtual int width() const = 0;
    virtual int height() const = 0;
    /// The directions the material was sampled at.
    virtual const Sampling& sampling() const = 0;

    /// BTF value (linear RGB) at texture position `uv` for light direction `wi` and view
    /// direction `wo` (unit vectors in the local frame, z = normal), interpolated smoothly:
    /// bilinear in space × barycentric over the ≤3 nearest views × ≤3 nearest lights.
    virtual Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const = 0;

    /// Value at exact sample indices and an integer texel (no interpolation).
    virtual Rgb eval_sample(int x, int y, int view, int light) const = 0;

    /// eval() for every query; out.size() must equal queries.size(). Implementations may
    /// reuse work between consecutive queries with the same directions.
    virtual void eval_batch(std::span<const Query> queries, std::span<Rgb> out) const {
        for (size_t i = 0; i < queries.size(); ++i)
            out[i] = eval(queries[i].uv, queries[i].wi, queries[i].wo);
    }
};

}  // namespace btf
