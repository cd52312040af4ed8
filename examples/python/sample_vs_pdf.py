#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Draw light directions with Material.sample and check them against Material.pdf.

A renderer that samples a BTF draws light directions wi for a fixed surface point and view from
uniform random numbers, and needs the density pdf(wi) of that draw for its estimate (and for
multiple importance sampling). Two things must agree: how often sample() lands in a region of the
hemisphere, and the integral of pdf() over that region. This example histograms many draws over
a grid of equal solid-angle bins in (cos theta, phi), integrates pdf() over each bin, and compares
the two with a chi-square test. It also uses the draws for what they are for: the Monte Carlo
estimate of the directional albedo, mean(value / pdf) / pi, against Material.albedo.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/sample_vs_pdf.py \\
        [PACKAGE] [--uv U,V] [--view THETA,PHI] [--samples N] [--out DIR]

PACKAGE is a btfkit package of any codec (mlvq samples from its own code-books, the others
through btfkit's tabulated sampler); without it, a synthetic 32 x 32 leather compressed with
mlvq. Writes DIR/sample_vs_pdf.png and DIR/histogram.npz (default DIR:
./out/examples/sample_vs_pdf).
"""

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt
import numpy as np

import btfkit as bk

NAME = "sample_vs_pdf"
COS_BINS, PHI_BINS = 12, 24  # 288 bins of equal solid angle, 2 pi / 288 sr each
SUBDIVISIONS = 8  # pdf() is integrated over a bin with 8 x 8 midpoints


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


def rgb(values, spec):
    """(r, g, b) as text, each number formatted with `spec`."""
    return "(" + ", ".join(format(v, spec) for v in values) + ")"


def cos_phi(w):
    """Unit vectors -> (cos theta, phi in [0, 2 pi)): coordinates in which area is solid angle."""
    return w[:, 2], np.mod(np.arctan2(w[:, 1], w[:, 0]), 2 * np.pi)


def bin_probabilities(material, uv, wo):
    """The probability that one draw lands in each (cos theta, phi) bin: the integral of pdf()
    over the bin, by the midpoint rule on SUBDIVISIONS^2 points (solid angle is area in
    (cos theta, phi), so every point stands for the same solid angle)."""
    nc, nphi = COS_BINS * SUBDIVISIONS, PHI_BINS * SUBDIVISIONS
    c = (np.arange(nc) + 0.5) / nc
    phi = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    C, PHI = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - C**2)
    wi = np.stack([s * np.cos(PHI), s * np.sin(PHI), C], axis=-1).reshape(-1, 3)
    count = len(wi)
    pdf = material.pdf(np.broadcast_to(uv, (count, 2)), np.broadcast_to(wo, (count, 3)), wi)
    point_solid_angle = 2 * np.pi / count
    per_point = (pdf * point_solid_angle).reshape(COS_BINS, SUBDIVISIONS, PHI_BINS, SUBDIVISIONS)
    return per_point.sum(axis=(1, 3))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("package", nargs="?", help="a btfkit package (default: a generated one)")
    parser.add_argument("--uv", type=numbers, default="0.3,0.6", help="surface position u,v")
    parser.add_argument("--view", type=numbers, default="30,0",
                        help="view direction theta,phi in degrees")
    parser.add_argument("--samples", type=int, default=200_000, help="directions drawn")
    parser.add_argument("--seed", type=int, default=1, help="seed of the uniform numbers")
    parser.add_argument("--out", default=f"out/examples/{NAME}", help="output folder")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    package = args.package
    if package is None:
        package = out / "leather.btfpkg"
        bk.compress(bk.synth("leather", 32, sampling="ubo81", seed=1), package, codec="mlvq")
        print(f"wrote {package}")
    material = bk.open_material(package)
    uv = np.array(args.uv)
    wo = direction(args.view)

    # N draws for one surface point and view: the same uv and wo on every row, fresh (xi1, xi2).
    n = args.samples
    xi = np.random.default_rng(args.seed).random((n, 2))
    wi, pdf, value = material.sample(np.broadcast_to(uv, (n, 2)), np.broadcast_to(wo, (n, 3)), xi)

    c, phi = cos_phi(wi)
    observed, _, _ = np.histogram2d(c, phi, bins=[COS_BINS, PHI_BINS],
                                    range=[[0, 1], [0, 2 * np.pi]])
    probability = bin_probabilities(material, uv, wo)
    expected = n * probability

    # Pearson's chi-square over the bins expected to hold at least 5 draws (the usual rule for
    # the chi-square approximation); the rest are pooled into one bin.
    big = expected >= 5
    obs = np.append(observed[big], observed[~big].sum())
    exp = np.append(expected[big], expected[~big].sum())
    keep = exp > 0
    chi2 = float(np.sum((obs[keep] - exp[keep]) ** 2 / exp[keep]))
    dof = int(keep.sum()) - 1
    z = (chi2 - dof) / np.sqrt(2 * dof)  # for large dof, chi-square ~ normal(dof, 2 dof)
    deviation = np.abs(observed[big] - expected[big]) / expected[big]
    print(f"{n} draws at uv ({uv[0]:g}, {uv[1]:g}), view ({args.view[0]:g}, {args.view[1]:g}): "
          f"chi-square {chi2:.1f} for {dof} degrees of freedom (z = {z:+.2f}); "
          f"largest relative deviation of a bin "
          f"{deviation.max():.3f} (one standard deviation there: "
          f"{1 / np.sqrt(expected[big][deviation.argmax()]):.3f})")

    # What the draws are for: (1/pi) * mean(value / pdf) estimates the directional albedo.
    weights = value / pdf[:, None]
    estimate = weights.mean(axis=0) / np.pi
    standard_error = weights.std(axis=0) / np.sqrt(n) / np.pi
    albedo = material.albedo(uv[None], wo[None])[0]
    print(f"albedo: Monte Carlo {rgb(estimate, '.4f')} +- {rgb(standard_error, '.1e')}, "
          f"Material.albedo {rgb(albedo, '.4f')}")

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.5))
    extent = [0, 360, 0, 1]
    top = max(observed.max(), expected.max())
    for ax, counts, title in [(axes[0], observed, "draws per bin (sample)"),
                              (axes[1], expected, "N x integral of pdf over the bin")]:
        image = ax.imshow(counts, origin="lower", extent=extent, aspect="auto", vmin=0, vmax=top)
        ax.set_xlabel("phi (degrees)")
        ax.set_ylabel("cos theta")
        ax.set_title(title)
        fig.colorbar(image, ax=ax)
    centres = (np.arange(COS_BINS) + 0.5) / COS_BINS
    axes[2].bar(centres, observed.sum(axis=1), width=1 / COS_BINS, alpha=0.5, label="sample()")
    axes[2].plot(centres, expected.sum(axis=1), "k.-", label="pdf() integrated")
    axes[2].set_xlabel("cos theta")
    axes[2].set_ylabel("draws")
    axes[2].set_title(f"over cos theta: chi2 / dof = {chi2 / dof:.3f}")
    axes[2].legend()
    fig.tight_layout()
    png = out / "sample_vs_pdf.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)
    np.savez(out / "histogram.npz", observed=observed, expected=expected, uv=uv, wo=wo,
             chi2=chi2, dof=dof)
    print(f"wrote {png} and {out / 'histogram.npz'}")

    check(np.all(wi[:, 2] >= 0) and np.all(pdf > 0) and np.isfinite(value).all(),
          "every draw is above the horizon with a positive pdf and a finite value")
    check(np.allclose(material.pdf(np.broadcast_to(uv, (n, 2)), np.broadcast_to(wo, (n, 3)), wi),
                      pdf, rtol=1e-4), "pdf() gives back the density sample() reported")
    check(abs(probability.sum() - 1) < 0.01, f"pdf() integrates to 1 over the hemisphere "
          f"({probability.sum():.4f}, midpoint rule)")
    # A correct sampler gives z around 0 (|z| < 2 in 95 % of seeds); a wrong pdf gives z in the
    # tens or hundreds at this many draws. The margin covers the midpoint rule's error.
    check(z < 4, f"the histogram agrees with the pdf (chi-square z = {z:+.2f} < 4)")
    check(np.all(np.abs(estimate - albedo) < 4 * standard_error + 1e-3 * albedo),
          "the Monte Carlo albedo agrees with Material.albedo (within 4 standard errors + 0.1 %)")
    check(plt.imread(png).shape[:2] == (450, 1400), "sample_vs_pdf.png is 1400 x 450 pixels")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except bk.Error as error:  # btfkit's one-line message
        sys.exit(f"{NAME}: {error}")
