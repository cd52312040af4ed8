#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Rate–distortion of coded factor storage against the old storages and mlvq (issue 23's
acceptance; docs/benchmarks.md, "Rate–distortion with coded factors").

For every material (the seven synthetic presets at SIZE² × 81 × 81 and the real measured view),
every configuration of CONFIGS is compressed with `btf compress` and measured with `btf quality`
(mean CIEDE2000 over every sample; BTF-CIELab on one viewing condition for the configurations on
a rate–distortion front). Results are cached in a JSON-lines file, so a rerun measures only what
is missing. Then, per material, the lower front of each family (old: f16/u8 storage of every
factorization codec; new: coded storage; mlvq) and the size of the new front at the mean ΔE00 of
each point of the old front and of mlvq's (interpolated in log size between neighbouring front
points), as a table.

Usage:
  python3 bench/coded_rd.py [--build build/release] [--size 128] [--work DIR] [--materials a,b]
                            [--btf-cielab] [--table] [--svg DIR]

--svg DIR writes one plot per material and measure (DIR/MATERIAL-de2000.svg, and
DIR/MATERIAL-btf-cielab.svg where every front point has BTF-CIELab): the compression ratio
against the error, one line per family's front.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys

PRESETS = ["woven_fabric", "embroidered_linen", "knitted_wool", "leather", "ceramic_tiles",
           "brushed_metal", "lacquered_wood"]
REAL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data",
                    "ubo2003-proposte-view000")


def old_configs():
    """f16 and u8 storage: fmf with and without log at several ranks (f16 only where it can
    compete: at twice u8's bytes it is on the front only for few components), and perceptual's
    CIELab planes."""
    out = []
    for log in ["", ",log=true"]:
        for c in [4, 8]:
            out.append(f"fmf:components={c},quantize=f16{log}")
        for c in [4, 8, 16, 32]:
            out.append(f"fmf:components={c},quantize=u8{log}")
    for c in [8, 16, 32]:
        out.append(f"perceptual:components={c},quantize=u8")
    # The log offset that suits the eye better (closer to CIELab's cube root), as the coded
    # configurations use it.
    for c in [4, 8, 16, 32]:
        out.append(f"fmf:components={c},quantize=u8,log=true,log-eps=0.03")
    # Local PCA and PCA over views: at these sizes only their smallest settings fit.
    out.append("lpca:clusters=4,components=4,quantize=u8,log=true,log-eps=0.03")
    out.append("pca-views:components=2,quantize=u8,log=true,log-eps=0.03")
    return out


def mlvq_configs():
    return [f"mlvq:threshold={t},chroma-threshold={t}" for t in ["3e-5", "1e-4", "3e-4"]]


def family(config):
    codec, params = config.split(":", 1)
    if codec == "mlvq":
        return "mlvq"
    return "new" if "quantize=coded" in params else "old"


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {r.stderr.strip()}")
    return r.stdout


class Sweep:
    def __init__(self, args):
        self.args = args
        self.btf = os.path.join(args.build, "btf")
        os.makedirs(args.work, exist_ok=True)
        self.cache_path = args.cache or os.path.join(args.work, f"results-{args.size}.jsonl")
        self.results = {}
        for path in [self.cache_path] + [p for p in args.read.split(",") if p]:
            if os.path.exists(path):
                with open(path) as f:
                    for line in f:
                        r = json.loads(line)
                        self.results[(r["material"], r["config"])] = r

    def source(self, material):
        if material == "real":
            return REAL
        path = os.path.join(self.args.work, f"{material}-{self.args.size}.h5")
        if not os.path.exists(path):
            run([self.btf, "-q", "synth", "--preset", material, "--size", str(self.args.size),
                 "-o", path])
        return path

    def save(self, r):
        self.results[(r["material"], r["config"])] = r
        with open(self.cache_path, "a") as f:  # the last line of a key wins when read
            f.write(json.dumps(r) + "\n")

    def package(self, material, config):
        return os.path.join(self.args.work, "packages",
                            f"{material}-{config.replace(':', '-').replace(',', '-')}.btfpkg")

    def compress(self, material, config):
        codec, params = config.split(":", 1)
        pkg = self.package(material, config)
        os.makedirs(os.path.dirname(pkg), exist_ok=True)
        cmd = [self.btf, "-q", "compress", self.source(material), "--codec", codec, "--no-error",
               "-o", pkg]
        for p in params.split(","):
            if p.startswith("target="):
                cmd += ["--target-size", p.split("=")[1]]
            else:
                cmd += ["-p", p]
        run(cmd)
        return pkg

    def measure(self, material, config):
        key = (material, config)
        if key in self.results:
            return self.results[key]
        src = self.source(material)
        pkg = self.compress(material, config)
        q = json.loads(run([self.btf, "-q", "quality", src, pkg, "--metrics", "de2000",
                            "--json"]))
        r = {"material": material, "config": config, "bytes": os.path.getsize(pkg),
             "de2000": q["de2000"]["mean"]}
        print(f"{material:18s} {config:55s} {r['bytes']:9d} B  ΔE00 {r['de2000']:.3f}",
              flush=True)
        self.save(r)
        return r

    def btf_cielab(self, material, config):
        r = self.results[(material, config)]
        if "btf_cielab" in r:
            return r
        src = self.source(material)
        pkg = self.package(material, config)
        if not os.path.exists(pkg):  # a result read from another run: made again, the same
            self.compress(material, config)
            # The same configuration within 0.1 % (container headers have grown by a few bytes
            # since some results were recorded); otherwise it is not the package measured.
            if abs(os.path.getsize(pkg) - r["bytes"]) > 0.001 * r["bytes"]:
                raise RuntimeError(f"{pkg}: {os.path.getsize(pkg)} bytes, the result read has "
                                   f"{r['bytes']}")
        q = json.loads(run([self.btf, "-q", "quality", src, pkg,
                            "--metrics", "btf-cielab", "--grid", "1", "--json"]))
        r["btf_cielab"] = q["btf_cielab"]["mean"]
        print(f"{material:18s} {config:55s} BTF-CIELab {r['btf_cielab']:.3f}", flush=True)
        self.save(r)
        return r


def listed(config):
    """Whether a cached result belongs to this script's configurations (the cache may hold
    others, from earlier trials)."""
    if family(config) == "new":
        return "target=" in config
    return config in old_configs() + mlvq_configs()


def old_points(sweep, material):
    return [r for (m, _), r in sweep.results.items() if m == material and
            family(r["config"]) == "old" and listed(r["config"])]


def front(points, measure="de2000"):
    """The lower-left front of (bytes, error) points: no other point is smaller and better."""
    pts = sorted(points, key=lambda r: (r["bytes"], r[measure]))
    out = []
    for p in pts:
        if not out or p[measure] < out[-1][measure]:
            out.append(p)
    return out


def size_at(fr, error, measure="de2000"):
    """Bytes the front needs for `error` (log-size interpolation between front points), or None
    outside the front's range."""
    for lo, hi in zip(fr, fr[1:]):
        if hi[measure] <= error <= lo[measure]:
            t = (lo[measure] - error) / (lo[measure] - hi[measure])
            return math.exp(math.log(lo["bytes"]) + t * (math.log(hi["bytes"]) -
                                                         math.log(lo["bytes"])))
    if fr and fr[0][measure] <= error:
        return fr[0]["bytes"]  # the smallest point is already good enough: an upper bound
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build/release")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--work", default="/tmp/btfkit_coded_rd")
    ap.add_argument("--materials", default=",".join(PRESETS + ["real"]))
    ap.add_argument("--families", default="old,new,mlvq")
    ap.add_argument("--btf-cielab", action="store_true",
                    help="also BTF-CIELab (one condition) of every front point")
    ap.add_argument("--new", default="fmf:components=48,quantize=coded,log=true,log-eps=0.03",
                    help="coded configurations (';'-separated), each compressed to half the "
                    "size of every point of the old front (--target-size)")
    ap.add_argument("--cache", default="", help="results file (default: WORK/results-SIZE.jsonl)")
    ap.add_argument("--read", default="", help="more results files to read (comma-separated)")
    ap.add_argument("--table", action="store_true", help="only print the tables from the cache")
    ap.add_argument("--svg", default="", help="write the fronts as SVG plots into this folder")
    ap.add_argument("--match", default="", help="only the configurations matching this regex")
    args = ap.parse_args()
    sweep = Sweep(args)
    materials = [m for m in args.materials.split(",") if m != "real" or os.path.isdir(REAL)]
    configs = []
    fams = args.families.split(",")
    if "old" in fams:
        configs += old_configs()
    if "mlvq" in fams:
        configs += mlvq_configs()
    configs = [c for c in configs if re.search(args.match, c)]
    if not args.table:
        for m in materials:
            for c in configs:
                try:
                    sweep.measure(m, c)
                except RuntimeError as e:
                    print(f"{m} {c}: {e}", file=sys.stderr)
            # New storage: a package of half the bytes of each point of the old front.
            if "new" in fams:
                for p in front(old_points(sweep, m)):
                    for t in args.new.split(";"):
                        try:
                            sweep.measure(m, f"{t},target={p['bytes'] // 2}")
                        except RuntimeError as e:
                            print(f"{m} {t}: {e}", file=sys.stderr)
    report(sweep, materials, args)
    if args.svg:
        write_svgs(sweep, materials, args)


def raw_bytes(material, size):
    """8-bit RGB bytes of the material: SIZE² × 81 × 81 for the presets, 256² × 1 × 81 for the real
    view."""
    return 256 * 256 * 81 * 3 if material == "real" else size * size * 81 * 81 * 3


FAMILY_STYLE = {"old": ("#888888", "old storage (f16, u8)"), "new": ("#d62728", "coded"),
                "mlvq": ("#1f77b4", "mlvq")}


def front_svg(material, fronts, raw, measure, label):
    """A rate–distortion plot: compression ratio (log axis) against `measure`, one polyline with
    markers per family's front."""
    pts = [(raw / r["bytes"], r[measure]) for f in fronts.values() for r in f]
    if not pts:
        return ""
    w, h, left, right, top, bottom = 640, 400, 64, 32, 36, 48
    lx = [math.log10(x) for x, _ in pts]
    x0, x1 = math.floor(min(lx)), math.ceil(max(lx))
    y1 = max(y for _, y in pts) * 1.05
    y1 = min(y1, 3 * sorted(y for _, y in pts)[len(pts) // 2])  # a far outlier is clipped
    sx = lambda x: left + (math.log10(x) - x0) / (x1 - x0) * (w - left - right)
    sy = lambda y: top + (1 - min(y, y1) / y1) * (h - top - bottom)
    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
         f'viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">',
         f'<rect width="{w}" height="{h}" fill="white"/>',
         f'<text x="{w / 2}" y="20" text-anchor="middle" font-size="14">{material}: {label} '
         f'against compression ratio (lower is better)</text>']
    for e in range(x0, x1 + 1):
        for m in [1, 2, 5]:
            x = m * 10 ** e
            if x0 <= math.log10(x) <= x1:
                o.append(f'<line x1="{sx(x):.1f}" x2="{sx(x):.1f}" y1="{top}" y2="{h - bottom}" '
                         f'stroke="#e0e0e0"/><text x="{sx(x):.1f}" y="{h - bottom + 16}" '
                         f'text-anchor="middle">{x:g}:1</text>')
    step = 10 ** math.floor(math.log10(y1 / 2))
    step *= 5 if y1 / step > 25 else 2 if y1 / step > 10 else 1
    y = 0.0
    while y <= y1:
        o.append(f'<line x1="{left}" x2="{w - right}" y1="{sy(y):.1f}" y2="{sy(y):.1f}" '
                 f'stroke="#e0e0e0"/><text x="{left - 6}" y="{sy(y) + 4:.1f}" '
                 f'text-anchor="end">{y:g}</text>')
        y += step
    o.append(f'<text x="{w / 2}" y="{h - 10}" text-anchor="middle">compression ratio '
             f'(raw 8-bit RGB bytes / package bytes)</text>')
    o.append(f'<text x="16" y="{h / 2}" text-anchor="middle" transform="rotate(-90 16 {h / 2})">'
             f'{label}</text>')
    for i, (f, (colour, name)) in enumerate(FAMILY_STYLE.items()):
        xy = [(sx(raw / r["bytes"]), sy(r[measure]), r) for r in fronts.get(f, [])]
        if xy:
            o.append(f'<polyline fill="none" stroke="{colour}" stroke-width="2" points="' +
                     " ".join(f"{x:.1f},{y:.1f}" for x, y, _ in xy) + '"/>')
        for x, y, r in xy:
            o.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="3.5" fill="{colour}"><title>'
                     f'{r["config"]}: {r["bytes"]} B, {r[measure]:.3f}</title></circle>')
        ly = h - bottom - 10 - 16 * (2 - i)  # bottom right: no front reaches it
        o.append(f'<line x1="{w - right - 170}" x2="{w - right - 150}" y1="{ly - 4}" '
                 f'y2="{ly - 4}" stroke="{colour}" stroke-width="2"/><text '
                 f'x="{w - right - 144}" y="{ly}">{name}</text>')
    o.append("</svg>")
    return "\n".join(o) + "\n"


def write_svgs(sweep, materials, args):
    os.makedirs(args.svg, exist_ok=True)
    for m in materials:
        rs = [r for (mm, _), r in sweep.results.items() if mm == m and listed(r["config"])]
        for measure, label in [("de2000", "mean CIEDE2000"), ("btf_cielab", "BTF-CIELab")]:
            have = [r for r in rs if measure in r]
            fronts = {f: front([r for r in have if family(r["config"]) == f], measure)
                      for f in FAMILY_STYLE}
            if measure != "de2000" and any(
                    measure not in r for f in ["old", "new", "mlvq"] for r in
                    front([r for r in rs if family(r["config"]) == f])):
                continue  # BTF-CIELab only where every ΔE00 front point has it
            svg = front_svg(m, fronts, raw_bytes(m, args.size), measure, label)
            if svg:
                with open(os.path.join(args.svg, f"{m}-{measure.replace('_', '-')}.svg"),
                          "w") as f:
                    f.write(svg)


def ratio_text(new, old):
    """new < 0: not reached, at most -new bytes measured (a lower bound of the ratio)."""
    return "—" if new is None else "> %.2f" % (-new / old) if new < 0 else "%.2f" % (new / old)


def report(sweep, materials, args):
    """Per material: the old front, and at each of its points the new front's size for the same
    mean ΔE00 (— outside the new front's range); then mlvq's points the same way; then a summary
    line per material."""
    print("| material | family | front point | bytes | mean ΔE00 | BTF-CIELab | new bytes at that ΔE00 "
          "| new / this |")
    print("|---|---|---|---|---|---|---|---|")
    summary = []
    for m in materials:
        rs = [r for (mm, _), r in sweep.results.items() if mm == m and listed(r["config"])]
        fronts = {f: front([r for r in rs if family(r["config"]) == f])
                  for f in ["old", "new", "mlvq"]}
        if args.btf_cielab:
            for f in fronts.values():
                for r in f:
                    try:
                        sweep.btf_cielab(m, r["config"])
                    except RuntimeError as e:
                        print(f"{m} {r['config']}: {e}", file=sys.stderr)
        ratios = {"old": [], "mlvq": []}
        missed = {"old": 0, "mlvq": 0}  # points beyond the new front's reach
        for f in ["old", "new", "mlvq"]:
            for p in fronts[f]:
                n = size_at(fronts["new"], p["de2000"]) if f != "new" else None
                if n is not None:
                    ratios[f].append(n / p["bytes"])
                elif f != "new" and fronts["new"] and \
                        fronts["new"][-1]["bytes"] >= 0.45 * p["bytes"]:
                    # Not reached by a new package of about half its size or more: the ratio at
                    # equal error is above that package's, and the target is not shown met.
                    missed[f] += 1
                    n = -fronts["new"][-1]["bytes"]
                cielab = "%.2f" % p["btf_cielab"] if "btf_cielab" in p else "—"
                print(f"| {m} | {f} | {p['config']} | {p['bytes']} | {p['de2000']:.3f} | {cielab} | "
                      f"{'' if f == 'new' else '—' if n is None else 'not reached' if n < 0 else int(n)} | "
                      f"{'' if f == 'new' else ratio_text(n, p['bytes'])} |")
        summary.append((m, ratios, missed))
    print()
    print("| material | old front points compared | new ≤ ½ old at | new / old | mlvq points compared "
          "| new smaller at | new / mlvq |")
    print("|---|---|---|---|---|---|---|")
    for m, ratios, missed in summary:
        o, v = ratios["old"] + [math.inf] * missed["old"], ratios["mlvq"] + [math.inf] * missed["mlvq"]
        span = lambda r: "—" if not r else "%.2f–%.2f" % (min(r), max(r)) if max(r) < math.inf \
            else "%.2f–(not reached)" % min(r)
        print(f"| {m} | {len(o)} | {sum(x <= 0.5 for x in o)} | {span(o)} | {len(v)} | "
              f"{sum(x < 1 for x in v)} | {span(v)} |")
    # The targets, counted two ways: a material where the new front is ≤ ½ of the old one at
    # every compared point, or at more than half of them (and smaller than mlvq likewise).
    every = lambda rs, ok: bool(rs) and all(ok(x) for x in rs)
    most = lambda rs, ok: bool(rs) and 2 * sum(ok(x) for x in rs) > len(rs)
    half, below = (lambda x: x <= 0.5), (lambda x: x < 1)
    counted = lambda r, mi, f: r[f] + [math.inf] * mi[f]
    print()
    for name, rule in [("every", every), ("most", most)]:
        print(f"Materials where the new front meets the target at {name} compared point(s): "
              f"≤ ½ old {sum(rule(counted(r, mi, 'old'), half) for _, r, mi in summary)} of {len(summary)}, "
              f"smaller than mlvq {sum(rule(counted(r, mi, 'mlvq'), below) for _, r, mi in summary)} of "
              f"{len(summary)}.")
    if args.btf_cielab:
        cielab_summary(sweep, materials)


def cielab_summary(sweep, materials):
    """The same comparison in BTF-CIELab: the fronts of the points measured in it, and at each old
    (mlvq) front point the new front's size for the same BTF-CIELab."""
    print()
    print("In BTF-CIELab (one viewing condition), at equal BTF-CIELab:")
    print()
    print("| material | old front points compared | new ≤ ½ old at | new / old | mlvq points compared "
          "| new smaller at | new / mlvq |")
    print("|---|---|---|---|---|---|---|")
    for m in materials:
        rs = [r for (mm, _), r in sweep.results.items() if mm == m and listed(r["config"]) and
              "btf_cielab" in r]
        fronts = {f: front([r for r in rs if family(r["config"]) == f], "btf_cielab")
                  for f in ["old", "new", "mlvq"]}
        cells = []
        for f, ok in [("old", lambda x: x <= 0.5), ("mlvq", lambda x: x < 1)]:
            ratios, missed = [], 0
            for p in fronts[f]:
                n = size_at(fronts["new"], p["btf_cielab"], "btf_cielab")
                if n is not None:
                    ratios.append(n / p["bytes"])
                elif fronts["new"] and fronts["new"][-1]["bytes"] >= 0.45 * p["bytes"]:
                    missed += 1  # beyond the reach of a new package of about half its size
            span = "—" if not ratios else "%.2f–%.2f" % (min(ratios), max(ratios))
            if missed:
                span += f" ({missed} not reached)"
            cells += [str(len(ratios) + missed), str(sum(ok(x) for x in ratios)), span]
        print(f"| {m} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
