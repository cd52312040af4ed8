#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Compress one material with three codecs and plot rate against perceptual error.

Each codec is run at two settings; every package is measured against the original with
bk.quality (every image of the BTF decoded and compared, CIEDE2000 per pixel), and the plot shows
the compression ratio (against 8-bit RGB raw data, as `btf compress` reports it) against the mean
Delta E00. Down and to the right is better: more compression for the same visible error.

On the small default material the angular factors that fmf and pca-views store (81 x 81
directions per component) outweigh the 16 x 16 texels' own; on a measured 256 x 256 material
the same settings compress many times more.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/codec_rate_distortion.py \\
        [MATERIAL] [--out DIR]

MATERIAL is any BTF btfkit reads (UBO2003 zip or folder, UBO2014 .btf, UTIA, btfkit HDF5);
without it, a synthetic 16 x 16 leather at the 81 x 81 UBO2003 directions. Real materials take
minutes rather than seconds: every codec reads all of it. Writes DIR/rate_distortion.png,
DIR/rate_distortion.json and the packages (default DIR: ./out/examples/codec_rate_distortion).
"""

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt
import numpy as np

import btfkit as bk

NAME = "codec_rate_distortion"

# (codec, label, parameters): two settings per codec, from coarse to fine. The parameters are the
# codecs' own (bk.codecs() lists them with their defaults; `btf codecs` prints the same).
SETTINGS = [
    ("fmf", "C=4", {"components": 4}),  # one truncated SVD of the whole BTF
    ("fmf", "C=16", {"components": 16}),
    ("pca-views", "C=1", {"components": 1}),  # one PCA per view (PCA-RF)
    ("pca-views", "C=4", {"components": 4}),
    ("mlvq", "t=1e-3", {"threshold": 1e-3}),  # vector quantization of the ABRDFs
    ("mlvq", "t=1e-5", {"threshold": 1e-5}),
]


def check(ok, what):
    """Prints what was verified, or stops with exit code 1 (the CTest test relies on it)."""
    if not ok:
        sys.exit(f"{NAME}: FAILED: {what}")
    print(f"ok: {what}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("material", nargs="?", help="a BTF (default: a generated 16x16 leather)")
    parser.add_argument("--out", default=f"out/examples/{NAME}", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    if args.material:
        source = bk.open(args.material)
    else:
        source = bk.synth("leather", 16, sampling="ubo81", seed=1)
    raw_8bit = source.width * source.height * source.num_views * source.num_lights * 3
    print(f"material: {source.width} x {source.height} texels, {source.num_views} views x "
          f"{source.num_lights} lights ({raw_8bit / 2**20:.1f} MiB as 8-bit RGB)")

    results = []
    for codec, label, params in SETTINGS:
        package = out / f"{codec}_{label.replace('=', '')}.btfpkg"
        bk.compress(source, package, codec=codec, **params)
        # The source as reference, the package as test: quality() decodes it through its codec.
        q = bk.quality(source, package, metrics=["rmse", "de2000"])
        size = package.stat().st_size
        results.append({"codec": codec, "label": label, "params": params, "bytes": size,
                        "ratio": raw_8bit / size, "rmse": q["rmse"], "de2000": q["de2000"]})
        print(f"{codec:9s} {label:7s} {size / 1024:8.1f} KiB  ratio {raw_8bit / size:6.1f}:1  "
              f"mean dE00 {q['de2000']['mean']:.3f}  p95 {q['de2000']['p95']:.2f}")

    fig, ax = plt.subplots(figsize=(7, 5))
    for codec in dict.fromkeys(r["codec"] for r in results):  # in order, once each
        rows = [r for r in results if r["codec"] == codec]
        ratio = [r["ratio"] for r in rows]
        error = [r["de2000"]["mean"] for r in rows]
        ax.plot(ratio, error, marker="o", label=codec)
        for r, x, y in zip(rows, ratio, error):
            ax.annotate(r["label"], (x, y), textcoords="offset points", xytext=(5, 5), fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("compression ratio (vs 8-bit RGB raw), log scale")
    ax.set_ylabel("mean CIEDE2000 over every image")
    ax.set_title(f"rate and perceptual error, {source.width}x{source.height} texels")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    png = out / "rate_distortion.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)
    (out / "rate_distortion.json").write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {png} and {out / 'rate_distortion.json'}")

    check(len({r["codec"] for r in results}) == 3, "three codecs were measured")
    check(all(r["bytes"] > 0 and np.isfinite(r["de2000"]["mean"]) and r["de2000"]["mean"] >= 0
              for r in results), "every package has a size and a finite mean dE00")
    # Eckart-Young: the best rank-16 approximation is closer than the best rank-4 one, and a
    # truncated SVD (fmf) is that approximation up to its randomized solver and half floats.
    fmf = [r for r in results if r["codec"] == "fmf"]
    check(fmf[1]["rmse"] < fmf[0]["rmse"] and fmf[1]["bytes"] > fmf[0]["bytes"],
          "fmf with 16 components is larger and closer (RMSE) than with 4")
    check(plt.imread(png).shape[:2] == (500, 700), "rate_distortion.png is 700 x 500 pixels")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except bk.Error as error:  # btfkit's one-line message
        sys.exit(f"{NAME}: {error}")
