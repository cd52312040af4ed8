#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The Python module against the C++ it wraps, in the same run (docs/benchmarks.md, "Python").

1. Evaluation: Material.eval on 2^20 random queries from NumPy (uv uniform, both directions
   uniform over the hemisphere, float64 arrays) against `btf bench eval --filter deterministic`
   on the same package (Material::eval_batch on its own random queries of the same
   distribution), each the best of --repeat runs, on one core (both under `taskset -c 0`) and on
   all cores.
2. UBO2003 import: Source.image for all 81 images of the real measured view into NumPy, one
   thread, from the extracted folder and from a stored zip of it, against ubo2003_import_bench's
   BM_ImportSingleThread (BtfSource::read_image in a C++ loop) on the same files.

Rounds alternate the two sides; the ratio of each round is Python / C++.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/python_bench.py \
        --package /tmp/base/fmf_default.btfpkg --rounds 5
"""
import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time
import zipfile

import numpy as np

import btfkit as bk

ROOT = pathlib.Path(__file__).resolve().parent.parent
VIEW = ROOT.parent / "shared/data/ubo2003-proposte-view000/tv000_pv000"


def hemisphere(rng, n):
    z = rng.random(n)
    phi = 2 * np.pi * rng.random(n)
    r = np.sqrt(np.maximum(0.0, 1 - z * z))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def python_eval_rate(material, n, repeat, rng):
    uv, wi, wo = rng.random((n, 2)), hemisphere(rng, n), hemisphere(rng, n)
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        out = material.eval(uv, wi, wo)
        best = min(best, time.perf_counter() - start)
    assert out.shape == (n, 3) and np.isfinite(out).all()
    return n / best / 1e6


def cxx_eval_rate(btf, package, n, repeat, threads, pin):
    cmd = [str(btf), "bench", "eval", str(package), "--filter", "deterministic", "--queries",
           str(n), "--repeat", str(repeat), "--threads", str(threads), "--json"]
    out = subprocess.run((["taskset", "-c", "0"] if pin else []) + cmd, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)["evals_per_s"] / 1e6


def python_import_rate(path, repeat):
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        src = bk.open(path)
        images = [src.image(0, light) for light in range(src.num_lights)]
        best = min(best, time.perf_counter() - start)
    assert len(images) == 81 and images[0].dtype == np.float32
    return 81 / best


def cxx_import_rates(bench):
    out = subprocess.run([str(bench), "--benchmark_filter=BM_ImportSingleThread/",
                          "--benchmark_format=json", "--benchmark_min_time=1"],
                         check=True, capture_output=True, text=True).stdout
    rates = {}
    for b in json.loads(out)["benchmarks"]:
        rates[b["name"].split("/")[1].split(":")[-1]] = b["images/s"]
    return rates  # {"0": folder, "1": zip} in images/s


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--package", required=True, help="a package to evaluate (e.g. fmf, 256²)")
    p.add_argument("--build", default=str(ROOT / "build/release"))
    p.add_argument("--queries", type=int, default=1 << 20)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    build = pathlib.Path(args.build)
    btf = build / "btf"
    rng = np.random.default_rng(1)
    material = bk.open_material(args.package)

    print(f"package {args.package}: {material.width}² texels; {args.queries} random queries, "
          f"best of {args.repeat}")
    print("| round | cores | C++ eval_batch (M/s) | Python m.eval (M/s) | Python / C++ |")
    print("|---|---|---|---|---|")
    for r in range(args.rounds):
        for cores in (1, 2):
            pin = cores == 1
            cxx = cxx_eval_rate(btf, args.package, args.queries, args.repeat, cores, pin)
            if pin:
                # This process pinned to core 0 for its turn: TBB then runs one thread.
                py = subprocess.run(
                    ["taskset", "-c", "0", sys.executable, __file__, "--package", args.package,
                     "--queries", str(args.queries), "--repeat", str(args.repeat),
                     "--eval-only"], check=True, capture_output=True, text=True,
                    env=os.environ).stdout.strip()
                py = float(py)
            else:
                py = python_eval_rate(material, args.queries, args.repeat, rng)
            print(f"| {r + 1} | {cores} | {cxx:.2f} | {py:.2f} | {py / cxx:.2f} |", flush=True)

    if not VIEW.is_dir():
        print(f"{VIEW}: not found; UBO2003 import not measured")
        return
    bench = build / "ubo2003_import_bench"
    with tempfile.TemporaryDirectory() as tmp:
        archive = pathlib.Path(tmp) / "view.zip"
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_STORED) as z:
            for f in sorted(VIEW.iterdir()):
                z.write(f, f"{VIEW.name}/{f.name}")
        print("\nUBO2003 real view, 81 images of 256², one thread, images/s (best of "
              f"{args.repeat} in Python; google-benchmark's mean in C++)")
        print("| round | source | C++ read_image loop | Python Source.image | Python / C++ |")
        print("|---|---|---|---|---|")
        for r in range(args.rounds):
            cxx = cxx_import_rates(bench)
            for key, name, path in (("0", "folder", VIEW), ("1", "zip", archive)):
                py = python_import_rate(path, args.repeat)
                print(f"| {r + 1} | {name} | {cxx[key]:.0f} | {py:.0f} | {py / cxx[key]:.2f} |",
                      flush=True)


if __name__ == "__main__":
    if "--eval-only" in sys.argv:
        a = argparse.ArgumentParser()
        a.add_argument("--package")
        a.add_argument("--queries", type=int)
        a.add_argument("--repeat", type=int)
        a.add_argument("--eval-only", action="store_true")
        ns = a.parse_args()
        print(python_eval_rate(bk.open_material(ns.package), ns.queries, ns.repeat,
                               np.random.default_rng(1)))
    else:
        main()
