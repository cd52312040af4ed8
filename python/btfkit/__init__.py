"""btfkit: measured material appearance (Bidirectional Texture Functions) from Python.

    import btfkit as bk
    src = bk.open("wool.zip")                # or bk.synth("woven_fabric", 64)
    img = src.image(0, 0)                     # float32 (H, W, 3), linear RGB
    bk.compress(src, "wool.btfpkg", codec="fmf", components=16)
    m = bk.open_material("wool.btfpkg")
    rgb = m.eval(uv, wi, wo)                  # (N, 2), (N, 3), (N, 3) -> (N, 3) float32

Errors from btfkit raise btfkit.Error with the same one-line message as the btf command;
malformed arguments raise ValueError naming the argument. See docs/python.md.
"""

import json as _json
import os as _os

from ._btfkit import Error, Material, Source, codecs, open, open_material, presets, synth
from ._btfkit import _compress, _open_input, _quality

__all__ = ["Error", "Material", "Source", "codecs", "compress", "images", "open",
           "open_material", "presets", "quality", "synth"]


def _source(value, name):
    if isinstance(value, Source):
        return value
    if isinstance(value, (str, bytes, _os.PathLike)):
        return _open_input(_os.fspath(value))
    raise ValueError(f"{name}: expected a btfkit.Source or a path")


def images(source):
    """Yields (view, light, image) for every image of a source, one read at a time (the whole
    BTF is never in memory at once)."""
    for view in range(source.num_views):
        for light in range(source.num_lights):
            yield view, light, source.image(view, light)


def compress(source, out, codec="fmf", **params):
    """Compresses a Source (or the BTF at a path) into the package `out` with `codec`.

    Keyword arguments are the codec's parameters, as `btf compress -p name=value` takes them
    (power_iterations=0 is power-iterations=0); codecs() lists each codec's parameters and
    defaults. An unknown parameter or a value out of range raises btfkit.Error, and `out` is
    written only when the package is complete.
    """
    if isinstance(source, (str, bytes, _os.PathLike)):
        source = open(source)
    if not isinstance(source, Source):
        raise ValueError("source: expected a btfkit.Source or a path")
    _compress(source, _os.fspath(out), codec, **params)


def quality(reference, test, metrics=("rmse", "lab", "de2000", "ssim"), cos_weight=False,
            peak=0.0):
    """How far `test` is from `reference`: a dict as `btf quality --json` prints it.

    Either may be a Source or a path; a package's path is measured through its codec's decoding.
    metrics: names from rmse, lab, de2000, ssim, btf-cielab (a list or a comma-separated string).
    """
    if not isinstance(metrics, str):
        metrics = ",".join(metrics)
    return _json.loads(_quality(_source(reference, "reference"), _source(test, "test"), metrics,
                                bool(cos_weight), float(peak)))
