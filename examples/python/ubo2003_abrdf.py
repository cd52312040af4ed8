#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Read a Bonn UBO2003 material and plot the ABRDF of one texel.

A texel's apparent BRDF (ABRDF) is the BTF at one fixed surface point: a matrix of view
directions x light directions, which holds the texel's reflectance together with the shadows,
masking and interreflections of the surface around it. UBO2003 stores a BTF image by image (one
JPEG per view and light), so one texel's ABRDF takes one pixel from each of the
num_views x num_lights images.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/ubo2003_abrdf.py \\
        [MATERIAL] [--texel X,Y] [--out DIR]

MATERIAL is a UBO2003 zip archive or folder: all 81 views, or some of them (for example the one
measured view in ../shared/data/ubo2003-proposte-view000). Without it, the example first writes a
small archive in UBO2003's own layout (a synthetic 32 x 32 woven fabric, 81 x 81 JPEGs) and checks
that reading it back gives the values that went in. Writes DIR/abrdf.png and DIR/abrdf.npz
(default DIR: ./out/examples/ubo2003_abrdf).
"""

import argparse
import io
import sys
import zipfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt
import numpy as np
from PIL import Image  # Pillow comes with Debian's python3-matplotlib

import btfkit as bk

NAME = "ubo2003_abrdf"


def check(ok, what):
    """Prints what was verified, or stops with exit code 1 (the CTest test relies on it)."""
    if not ok:
        sys.exit(f"{NAME}: FAILED: {what}")
    print(f"ok: {what}")


def srgb_encode(linear):
    """Linear RGB in [0, 1] -> sRGB-encoded values in [0, 1] (IEC 61966-2-1's transfer curve)."""
    c = np.clip(linear, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def ubo2003_fields(theta, phi, theta_prefix, phi_prefix, separator):
    """'tl015 pl060': the angles of a direction in whole degrees, as UBO2003 file names write them
    (phi is 000 at the pole)."""
    theta = int(round(theta))
    phi = int(round(phi)) % 360 if theta != 0 else 0
    return f"{theta_prefix}{theta:03d}{separator}{phi_prefix}{phi:03d}"


def write_ubo2003_zip(source, path):
    """Writes `source` (sampled at the 81 UBO2003 directions) as a UBO2003 zip archive: one
    8-bit sRGB JPEG per view and light, named

        tvTTT_pvPPP/NNNNN tlTTT plPPP tvTTT pvPPP.jpg     (NNNNN = 81 * light + view)

    which is how the Bonn database's "MANYFILES" layout stores a material."""
    views, lights = source.view_degrees, source.light_degrees
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as archive:
        for view, light, image in bk.images(source):
            folder = ubo2003_fields(*views[view], "tv", "pv", "_")
            name = "{:05d} {} {}.jpg".format(81 * light + view,
                                             ubo2003_fields(*lights[light], "tl", "pl", " "),
                                             ubo2003_fields(*views[view], "tv", "pv", " "))
            pixels = np.round(srgb_encode(image) * 255).astype(np.uint8)
            jpeg = io.BytesIO()
            # 4:4:4 (no chroma subsampling): a woven fabric's colour changes from texel to texel.
            Image.fromarray(pixels).save(jpeg, format="JPEG", quality=98, subsampling=0)
            archive.writestr(f"{folder}/{name}", jpeg.getvalue())


def integers(text):
    """'x,y' -> (x, y): the type of --texel."""
    try:
        x, y = (int(t) for t in text.split(","))
        return x, y
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected two integers x,y, got '{text}'") from None


def texel_abrdf(source, x, y):
    """The (num_views, num_lights, 3) ABRDF of texel (x, y): one pixel of every image. The images
    are read one at a time (bk.images), so the whole BTF is never in memory."""
    abrdf = np.empty((source.num_views, source.num_lights, 3), np.float32)
    for view, light, image in bk.images(source):
        abrdf[view, light] = image[y, x]
    return abrdf


def plot(abrdf, source, x, y, png):
    """Left: the ABRDF as a picture (rows: views, columns: lights, both in the file order, which
    climbs in theta ring by ring). Right: the texel in the image at the first view and light."""
    scale = 1.0 / max(np.percentile(abrdf, 99.5), 1e-6)  # exposure: 99.5 % of values below white
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 5),
                                      gridspec_kw={"width_ratios": [2, 1]})
    left.imshow(srgb_encode(abrdf * scale), interpolation="nearest", aspect="auto")
    left.set_xlabel("light index (theta rises ring by ring)")
    left.set_ylabel("view index")
    left.set_title(f"ABRDF of texel ({x}, {y}): {abrdf.shape[0]} views x {abrdf.shape[1]} lights")
    # Mark where the light elevation changes: each band is one ring of the hemisphere.
    thetas = source.light_degrees[:, 0]
    for index in np.flatnonzero(np.diff(thetas)) + 1:
        left.axvline(index - 0.5, color="white", linewidth=0.5, alpha=0.6)
    first = source.image(0, 0)
    right.imshow(srgb_encode(first / max(first.max(), 1e-6)), interpolation="nearest")
    right.plot([x], [y], marker="s", markersize=8, markerfacecolor="none", color="red")
    right.set_title("view 0, light 0: the texel (red)")
    right.axis("off")
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("material", nargs="?",
                        help="UBO2003 zip archive or folder (default: a generated 32x32 one)")
    parser.add_argument("--texel", type=integers, help="x,y of the texel (default: the centre)")
    parser.add_argument("--out", default=f"out/examples/{NAME}", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    reference = None
    material = args.material
    if material is None:
        # The same directions as the database (the 81 of UBO2003 for lights and views).
        reference = bk.synth("woven_fabric", 32, sampling="ubo81", seed=1)
        material = out / "woven_fabric_ubo2003.zip"
        write_ubo2003_zip(reference, material)
        print(f"wrote {material}: {reference.num_views} x {reference.num_lights} JPEGs of "
              f"{reference.width} x {reference.height} texels")

    source = bk.open(material)  # recognizes the archive by its file names
    print(f"{material}: {source.format}, {source.width} x {source.height} texels, "
          f"{source.num_views} views x {source.num_lights} lights")
    if args.texel:
        x, y = args.texel
    else:
        x, y = source.width // 2, source.height // 2
    if not (0 <= x < source.width and 0 <= y < source.height):
        sys.exit(f"{NAME}: --texel {x},{y} is outside the {source.width} x {source.height} texels")

    abrdf = texel_abrdf(source, x, y)
    png = out / "abrdf.png"
    plot(abrdf, source, x, y, png)
    np.savez(out / "abrdf.npz", abrdf=abrdf, view_degrees=source.view_degrees,
             light_degrees=source.light_degrees, texel=np.array([x, y]))
    print(f"wrote {png} and {out / 'abrdf.npz'}")

    check(abrdf.shape == (source.num_views, source.num_lights, 3),
          f"the ABRDF is {source.num_views} views x {source.num_lights} lights x RGB")
    check(np.isfinite(abrdf).all() and abrdf.min() >= 0, "its values are finite and not negative")
    check(abrdf.max() > abrdf.min(), "it is not constant")
    check(plt.imread(png).shape[:2] == (500, 1100), "abrdf.png is 1100 x 500 pixels")
    if reference is not None:
        # What went into the archive, through 8-bit sRGB and JPEG: compare as the JPEGs store it.
        expected = texel_abrdf(reference, x, y)
        error = np.abs(srgb_encode(abrdf) - srgb_encode(expected)) * 255
        print(f"JPEG round trip of the texel: mean |error| {error.mean():.2f}, "
              f"max {error.max():.1f} (8-bit sRGB steps)")
        check(error.mean() < 2 and error.max() < 16,
              "the archive read back matches the material that was written to within JPEG error")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except bk.Error as error:  # btfkit's one-line message, e.g. "x.zip: no such file or folder"
        sys.exit(f"{NAME}: {error}")
