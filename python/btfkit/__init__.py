# SPDX-License-Identifier: MIT
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

from ._btfkit import (Error, Material, Source, __version__, codecs, open, open_material,
                      open_materials, presets, synth)
from ._btfkit import _compress, _decompress, _open_input, _quality, _render, _RenderOverrides

__all__ = ["Error", "Material", "Source", "codecs", "compress", "decompress", "images", "open",
           "open_material", "open_materials", "presets", "quality", "render", "synth"]

_PATH = (str, bytes, _os.PathLike)


def _source(value, name):
    if isinstance(value, Source):
        return value
    if isinstance(value, _PATH):
        return _open_input(_os.fspath(value))
    raise ValueError(f"{name}: expected a btfkit.Source or a path")


def _callback(progress, name="progress"):
    if progress is not None and not callable(progress):
        raise ValueError(f"{name}: expected a callable progress(stage, done, total) or None")
    return progress


def images(source):
    """Yields (view, light, image) for every image of a source, one read at a time (the whole
    BTF is never in memory at once)."""
    for view in range(source.num_views):
        for light in range(source.num_lights):
            yield view, light, source.image(view, light)


def compress(source, out, codec="fmf", progress=None, **params):
    """Compresses a Source (or the BTF at a path) into the package `out` with `codec`.

    Keyword arguments are the codec's parameters, as `btf compress -p name=value` takes them
    (power_iterations=0 is power-iterations=0); they are listed below and by codecs(). An unknown
    parameter or a value out of range raises btfkit.Error before the codec reads any image, and
    `out` is written only when the package is complete.

    source may also be a list of Sources or paths: codecs that share code-books (mlvq) put them
    all in one package (a Material of each: open_materials; each named by its path, or by its
    source's own name); others raise btfkit.Error.

    progress: None, or a callable progress(stage, done, total) called on this thread as the work
    advances; an exception it raises cancels the work. Ctrl-C cancels too (KeyboardInterrupt),
    leaving no file behind.
    """
    several = isinstance(source, (list, tuple))
    sources = [_source(s, "source") for s in (source if several else [source])]
    names = [_os.fsdecode(s) if isinstance(s, _PATH) else ""
             for s in (source if several else [source])]
    if not sources:
        raise ValueError("source: an empty list")
    _compress(sources, names, _os.fspath(out), codec, params, _callback(progress))


def decompress(package, out, half=True, deflate=0, format=None, progress=None):
    """Decodes a package (or a prefix of one) to a raw BTF, as `btf decompress` does: btfkit
    HDF5 when `out` ends in .h5 (half floats unless half=False; deflate level 0-9), otherwise a
    UTIA image set in the new folder `out` (format "png" or "exr"; default exr for HDR, png
    otherwise). progress and Ctrl-C as for compress()."""
    _decompress(_os.fspath(package), _os.fspath(out), bool(half), int(deflate), format or "",
                _callback(progress))


def render(scene, spp=None, size=None, seed=None, integrator=None, max_depth=None, filter=None,
           time=None, material=None, sampling="material", progress=None):
    """Renders a scene (docs/scenes.md) with the CPU path tracer, as `btf render` does, and
    returns its linear radiance as a float32 (height, width, 3) array.

    scene: a path to a scene file, or a dict with the file's content (relative paths resolve
    against the current folder). The other arguments override the scene's "render" block:
    spp (samples per pixel), size ((width, height)), seed, integrator ("path" or "direct"),
    max_depth, filter ("stochastic" or "deterministic"), time (seconds; with spp=0 the only
    limit). material: a package (or .btf or raw BTF) that replaces every "btf" material of the
    scene. sampling: "material", "generic" or "cosine". progress and Ctrl-C as for compress().
    """
    def at_least(name, value, low, kind=int):
        if value is None:
            return None
        value = kind(value)
        if value < low:
            raise ValueError(f"{name}: must be at least {low}")
        return value

    o = _RenderOverrides()
    if integrator is not None:
        if integrator not in ("path", "direct"):
            raise ValueError(f"integrator: expected 'path' or 'direct', got {integrator!r}")
        o.integrator = integrator
    if filter is not None:
        if filter not in ("stochastic", "deterministic"):
            raise ValueError(f"filter: expected 'stochastic' or 'deterministic', got {filter!r}")
        o.filter = filter
    for name, value, low, kind in (("spp", spp, 0, int), ("max_depth", max_depth, 1, int),
                                   ("seed", seed, 0, int), ("time_limit", time, 0, float)):
        value = at_least("time" if name == "time_limit" else name, value, low, kind)
        if value is not None:
            setattr(o, name, value)
    if size is not None:
        try:
            o.width, o.height = (int(v) for v in size)
        except (TypeError, ValueError):
            raise ValueError("size: expected (width, height)") from None
        if o.width < 1 or o.height < 1:
            raise ValueError("size: width and height must be at least 1")
    if isinstance(scene, dict):
        name, text, base = "<scene dict>", _json.dumps(scene), _os.getcwd()
    elif isinstance(scene, _PATH):
        name, text, base = _os.fspath(scene), "", ""
    else:
        raise ValueError("scene: expected a path or a dict")
    material = None if material is None else _os.fspath(material)
    return _render(name, text, base, material, sampling, o, _callback(progress))


def quality(reference, test, metrics=("rmse", "lab", "de2000", "ssim"), cos_weight=False,
            peak=0.0, progress=None):
    """How far `test` is from `reference`: a dict as `btf quality --json` prints it.

    Either may be a Source or a path; a package's path is measured through its codec's decoding.
    metrics: names from rmse, lab, de2000, ssim, btf-cielab (a list or a comma-separated string).
    progress and Ctrl-C as for compress().
    """
    if not isinstance(metrics, str):
        metrics = ",".join(metrics)
    return _json.loads(_quality(_source(reference, "reference"), _source(test, "test"), metrics,
                                bool(cos_weight), float(peak), _callback(progress)))


def _codec_parameters_doc():
    lines = ["", "Codecs and their parameters (name=default [range]: meaning):"]
    for name, (description, params) in codecs().items():
        lines += ["", f"{name}: {description}"]
        for key, p in params.items():
            shown = f" [{p['range']}]" if p["type"] in ("int", "number") else ""
            lines.append(f"    {key.replace('-', '_')}={p['default']}{shown}: {p['help']}")
    return "\n".join(lines)


if compress.__doc__:  # None under python -OO
    compress.__doc__ += _codec_parameters_doc()
