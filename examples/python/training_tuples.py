#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Make (uv, wi, wo, value) training tuples from a material for a learning pipeline.

Neural and other learned BTF models train on tuples of a surface position, a light direction, a
view direction and the RGB value there. btfkit hands them over as plain NumPy arrays in two ways:

  * random queries: any uv and any directions, values from Material.eval (interpolated between
    the measured texels and directions exactly as the renderer and the metrics see them);
  * exact samples: integer (x, y, view, light) indices, values from Material.eval_sample (the
    stored samples themselves, no interpolation), with the uv of the texel centre and the
    measured directions from Material.views and Material.lights.

Both are saved as .npz (np.load gives them back) and, to show the data is usable, fitted with a
tiny linear least-squares model of the directions, scored on tuples it did not see.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/training_tuples.py \\
        [PACKAGE] [--count N] [--out DIR]

PACKAGE is a btfkit package of any codec; without it, a synthetic 32 x 32 knitted wool compressed
with fmf. Writes DIR/queries.npz and DIR/samples.npz (default DIR:
./out/examples/training_tuples).
"""

import argparse
import sys
from pathlib import Path

import numpy as np

import btfkit as bk

NAME = "training_tuples"


def check(ok, what):
    """Prints what was verified, or stops with exit code 1 (the CTest test relies on it)."""
    if not ok:
        sys.exit(f"{NAME}: FAILED: {what}")
    print(f"ok: {what}")


def cosine_hemisphere(rng, n):
    """n directions with density cos(theta) / pi over the upper hemisphere (Malley's method: a
    uniform point on the unit disk, lifted onto the hemisphere), so that grazing directions,
    where a BTF is least reliable and matters least, are rarer."""
    r = np.sqrt(rng.random(n))
    phi = 2 * np.pi * rng.random(n)
    x, y = r * np.cos(phi), r * np.sin(phi)
    return np.stack([x, y, np.sqrt(np.maximum(0.0, 1 - x * x - y * y))], axis=1)


def random_queries(material, rng, n):
    """n random tuples: uv uniform over the texture, directions cosine-distributed, values from
    Material.eval. Stored as float32, the precision a network trains in."""
    uv = rng.random((n, 2))
    wi, wo = cosine_hemisphere(rng, n), cosine_hemisphere(rng, n)
    rgb = material.eval(uv, wi, wo)
    return {"uv": uv.astype(np.float32), "wi": wi.astype(np.float32),
            "wo": wo.astype(np.float32), "rgb": rgb}


def exact_samples(material, rng, n):
    """n stored samples at random (x, y, view, light) indices, with their uv and directions."""
    limits = [material.width, material.height, len(material.views), len(material.lights)]
    index = np.stack([rng.integers(0, limit, n) for limit in limits], axis=1)
    rgb = material.eval_sample(index)
    uv = (index[:, :2] + 0.5) / [material.width, material.height]  # texel centres
    return {"index": index.astype(np.int32), "uv": uv.astype(np.float32),
            "wi": material.lights[index[:, 3]].astype(np.float32),
            "wo": material.views[index[:, 2]].astype(np.float32), "rgb": rgb}


def features(wi, wo):
    """A few functions of the directions for a linear model: the cosines and the half vector's
    alignment with the normal (where a specular lobe peaks), each times cos(theta_i): a BTF value
    is pi * f_r * cos(theta_i), the photograph of a surface under a light includes its
    foreshortening ("Units and the BTF value" in docs/scenes.md)."""
    ci, co = wi[:, 2], wo[:, 2]
    h = wi + wo
    nh = h[:, 2] / np.linalg.norm(h, axis=1)
    # > 0 where the light comes from the viewer's side (back-scattering), < 0 from opposite it
    tangential = wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1]
    columns = [np.ones_like(ci), co, co * co, nh**8, nh**32, tangential]
    return np.stack([c * ci for c in columns], axis=1)


def r_squared(truth, prediction):
    """1 - residual variance / variance: 1 is perfect, 0 is no better than the mean."""
    return 1 - np.sum((truth - prediction) ** 2) / np.sum((truth - truth.mean(axis=0)) ** 2)


def describe(name, arrays):
    for key, value in arrays.items():
        print(f"  {name}[{key!r}]: shape {value.shape}, dtype {value.dtype}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("package", nargs="?", help="a btfkit package (default: a generated one)")
    parser.add_argument("--count", type=int, default=100_000, help="tuples of each kind")
    parser.add_argument("--seed", type=int, default=1, help="seed of the random queries")
    parser.add_argument("--out", default=f"out/examples/{NAME}", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    package = args.package
    if package is None:
        package = out / "knitted_wool.btfpkg"
        bk.compress(bk.synth("knitted_wool", 32, sampling="ubo81", seed=1), package,
                    codec="fmf", components=8)
        print(f"wrote {package}")
    material = bk.open_material(package)
    rng = np.random.default_rng(args.seed)

    queries = random_queries(material, rng, args.count)
    samples = exact_samples(material, rng, args.count)
    np.savez(out / "queries.npz", **queries)
    np.savez(out / "samples.npz", **samples)
    print(f"wrote {out / 'queries.npz'} and {out / 'samples.npz'}:")
    describe("queries", queries)
    describe("samples", samples)

    # The linear model: value ~ features(wi, wo) @ beta, one beta per channel, fitted on 80 % of
    # the random queries and scored on the other 20 %. It knows nothing of uv, so it learns the
    # material's average reflectance; what is left is the texture a real model would learn.
    split = int(0.8 * args.count)
    X = features(queries["wi"].astype(np.float64), queries["wo"].astype(np.float64))
    y = queries["rgb"].astype(np.float64)
    beta, *_ = np.linalg.lstsq(X[:split], y[:split], rcond=None)
    held_out = r_squared(y[split:], X[split:] @ beta)
    on_samples = r_squared(samples["rgb"].astype(np.float64),
                           features(samples["wi"].astype(np.float64),
                                    samples["wo"].astype(np.float64)) @ beta)
    print(f"least squares over {X.shape[1]} direction features: R^2 {held_out:.3f} on held-out "
          f"queries, {on_samples:.3f} on the exact samples")

    loaded = np.load(out / "queries.npz")
    check(all(np.array_equal(loaded[k], v) for k, v in queries.items()),
          "queries.npz gives back the arrays that were saved")
    for name, tuples in [("queries", queries), ("samples", samples)]:
        rgb = tuples["rgb"]
        check(rgb.shape == (args.count, 3) and rgb.dtype == np.float32 and np.isfinite(rgb).all(),
              f"{name}: {args.count} finite float32 RGB values")
        # A truncated factorization (fmf, pca-views, lpca) rings slightly below zero in places
        # (docs/codecs.md); clamp the targets if a model needs them non-negative.
        print(f"  {name}: {np.mean(rgb < 0):.3%} of values below zero (smallest {rgb.min():.4f})")
    # At a texel centre and measured directions, interpolating changes nothing: eval() and
    # eval_sample() give the same value, so both kinds of tuple describe one function.
    first = slice(0, 1000)
    again = material.eval(samples["uv"][first], samples["wi"][first], samples["wo"][first])
    check(np.allclose(again, samples["rgb"][first], rtol=1e-3, atol=1e-5),
          "eval() at the exact samples' uv and directions gives their values")
    # On the default material the directions explain most of the variance; on any material the
    # model must at least beat the constant prediction.
    minimum = 0.5 if args.package is None else 0.0
    check(held_out > minimum,
          f"the linear model predicts held-out values (R^2 {held_out:.3f} > {minimum})")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except bk.Error as error:  # btfkit's one-line message
        sys.exit(f"{NAME}: {error}")
