#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Evaluate a compressed material on a grid of surface positions and save it as a picture.

Material.eval(uv, wi, wo) answers any number of random-access queries at once: here one query per
pixel of a 512 x 512 grid over the texture, all with the same light and view direction. That is
what a renderer asks of a BTF on a flat surface under a distant light, seen from far away.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/eval_texture.py \\
        [PACKAGE] [--light THETA,PHI] [--view THETA,PHI] [--repeat N] [--size N] [--out DIR]

PACKAGE is a btfkit package of any codec (or a UBO2014 .btf file); without it, a synthetic
32 x 32 woven fabric compressed with fmf. Directions are in degrees in the sample's frame (theta
from the normal, phi from the texture's u axis). Writes DIR/texture.png (tone-mapped sRGB) and
DIR/texture.npz (the linear values) (default DIR: ./out/examples/eval_texture).
"""

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt
import numpy as np

import btfkit as bk

NAME = "eval_texture"


def check(ok, what):
    """Prints what was verified, or stops with exit code 1 (the CTest test relies on it)."""
    if not ok:
        sys.exit(f"{NAME}: FAILED: {what}")
    print(f"ok: {what}")


def numbers(text):
    """'a,b' -> (a, b): the type of the options that take two numbers."""
    try:
        a, b = (float(t) for t in text.split(","))
        return a, b
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected two numbers a,b, got '{text}'") from None


def direction(theta_phi):
    """(theta, phi) in degrees -> a unit vector, z along the surface normal."""
    theta, phi = np.radians(theta_phi)
    return np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def tone_map(linear, white):
    """Linear RGB -> 8-bit sRGB: `white` maps to 1, above it clips (a plain exposure, no curve)."""
    c = np.clip(linear / white, 0.0, 1.0)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    return np.round(srgb * 255).astype(np.uint8)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("package", nargs="?", help="a btfkit package (default: a generated one)")
    parser.add_argument("--light", type=numbers, default="60,0",
                        help="light direction theta,phi in degrees")
    parser.add_argument("--view", type=numbers, default="0,0",
                        help="view direction theta,phi in degrees")
    parser.add_argument("--repeat", type=float, default=2,
                        help="how many times the texture repeats across the picture")
    parser.add_argument("--size", type=int, default=512, help="picture size in pixels")
    parser.add_argument("--out", default=f"out/examples/{NAME}", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    package = args.package
    if package is None:
        package = out / "woven_fabric.btfpkg"
        bk.compress(bk.synth("woven_fabric", 32, sampling="ubo81", seed=1), package,
                    codec="fmf", components=8)
        print(f"wrote {package}")
    material = bk.open_material(package)
    wi, wo = direction(args.light), direction(args.view)

    # One (u, v) per pixel, at pixel centres; u runs along image columns, v along rows, and the
    # material repeats outside [0, 1).
    n = args.size
    t = (np.arange(n) + 0.5) / n * args.repeat
    u, v = np.meshgrid(t, t)  # (n, n) each: u varies along a row
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    # Every query has its own directions; broadcasting one light and view to n*n rows costs
    # 2 x 24 bytes per query and keeps the call general.
    rgb = material.eval(uv, np.broadcast_to(wi, (n * n, 3)), np.broadcast_to(wo, (n * n, 3)))
    picture = rgb.reshape(n, n, 3)

    white = max(float(np.percentile(picture, 99.5)), 1e-6)
    png = out / "texture.png"
    plt.imsave(png, tone_map(picture, white))
    np.savez(out / "texture.npz", linear_rgb=picture, light=wi, view=wo, repeat=args.repeat)
    print(f"{package}: {material.width} x {material.height} texels, evaluated at {n} x {n} "
          f"positions; mean value {picture.mean():.4f}; wrote {png} and {out / 'texture.npz'}")

    check(picture.shape == (n, n, 3) and picture.dtype == np.float32,
          f"the picture is {n} x {n} RGB float32")
    # (A truncated factorization may ring slightly below zero in places: docs/codecs.md. The tone
    # mapping clips those to black.)
    check(np.isfinite(picture).all(), "every value is finite")
    check(picture.max() > picture.min(), "the picture is not constant")
    check(plt.imread(png).shape[:2] == (n, n), f"texture.png is {n} x {n} pixels")

    # The material repeats: shifting uv by whole numbers changes nothing.
    rows = np.random.default_rng(1).choice(n * n, 1000, replace=False)
    shifted = material.eval(uv[rows] + [1.0, -3.0], np.broadcast_to(wi, (1000, 3)),
                            np.broadcast_to(wo, (1000, 3)))
    check(np.allclose(shifted, rgb[rows], rtol=1e-5, atol=1e-7),
          "uv + (1, -3) gives the same values")

    # At a texel centre and measured directions, the interpolated value is the stored sample.
    light = int(np.argmax(material.lights @ wi))
    view = int(np.argmax(material.views @ wo))
    if material.lights[light] @ wi > 1 - 1e-9 and material.views[view] @ wo > 1 - 1e-9:
        xy = np.array([[x, y] for y in range(material.height) for x in range(material.width)])
        centres = (xy + 0.5) / [material.width, material.height]
        count = len(xy)
        interpolated = material.eval(centres, np.broadcast_to(wi, (count, 3)),
                                     np.broadcast_to(wo, (count, 3)))
        exact = material.eval_sample(np.column_stack([xy, np.full(count, view),
                                                      np.full(count, light)]))
        check(np.allclose(interpolated, exact, rtol=1e-4, atol=1e-6),
              f"at texel centres eval() equals eval_sample() (view {view}, light {light})")
    else:
        print("(the light or view is between measured directions: the check against "
              "eval_sample() needs measured ones)")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except bk.Error as error:  # btfkit's one-line message
        sys.exit(f"{NAME}: {error}")
