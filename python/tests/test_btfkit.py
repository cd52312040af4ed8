# SPDX-License-Identifier: MIT
import json
import math
import re
import struct

import numpy as np
import pytest

import btfkit as bk


def test_source_describes_its_sampling(source):
    assert (source.width, source.height) == (8, 8)
    assert (source.num_views, source.num_lights) == (81, 81)
    assert source.views.shape == (81, 3) and source.lights.shape == (81, 3)
    np.testing.assert_allclose(np.linalg.norm(source.views, axis=1), 1.0, rtol=1e-12)
    assert (source.views[:, 2] >= 0).all()
    # The degrees describe the same directions as the vectors.
    theta, phi = np.radians(source.view_degrees).T
    np.testing.assert_allclose(source.views[:, 2], np.cos(theta), atol=1e-12)
    np.testing.assert_allclose(source.views[:, 0], np.sin(theta) * np.cos(phi), atol=1e-12)


def test_images_are_float32_rgb_and_iterate_one_by_one(source):
    image = source.image(3, 5)
    assert image.dtype == np.float32 and image.shape == (8, 8, 3)
    assert np.isfinite(image).all() and image.max() > 0
    seen = 0
    for view, light, img in bk.images(source):
        if (view, light) == (3, 5):
            np.testing.assert_array_equal(img, image)
        seen += 1
    assert seen == 81 * 81


def test_bad_indices_and_paths_raise(source, tmp_path):
    with pytest.raises(IndexError, match="view 81 is out of range"):
        source.image(81, 0)
    missing = tmp_path / "nothing.h5"
    with pytest.raises(bk.Error, match="nothing.h5"):
        bk.open(missing)
    with pytest.raises(bk.Error):
        bk.synth("no_such_preset", 8)


def test_compress_refuses_bad_parameters_and_writes_nothing(source, tmp_path):
    out = tmp_path / "bad.btfpkg"
    with pytest.raises(bk.Error, match="unknown parameter 'componentz'"):
        bk.compress(source, out, codec="fmf", componentz=4)
    with pytest.raises(bk.Error, match="components"):
        bk.compress(source, out, codec="fmf", components=-1)
    assert not out.exists()


def test_version_is_the_packages_writer(source, tmp_path):
    assert re.fullmatch(r"\d+\.\d+\.\d+", bk.__version__), bk.__version__
    out = tmp_path / "m.btfpkg"
    bk.compress(source, out, codec="fmf", components=2)
    data = out.read_bytes()
    assert data[:8] == b"\x89BTFPKG\n"
    header = json.loads(data[24:24 + struct.unpack_from("<I", data, 12)[0]])
    assert header["writer"] == "btfkit " + bk.__version__


def test_codecs_list_their_parameters():
    codecs = bk.codecs()
    assert {"fmf", "mlvq", "lpca"} <= set(codecs)
    description, params = codecs["fmf"]
    assert "components" in params and "power-iterations" in params
    assert params["components"]["type"] == "int" and params["components"]["range"] == "1..4096"
    # The shared factorization parameters are the same declaration in every such codec.
    for name in ("fmf", "pca-views", "lpca", "perceptual"):
        assert codecs[name][1]["quantize"] == {
            "type": "choice", "default": "f16", "range": "f32|f16|u8|coded",
            "help": "factor storage: f32, f16, u8 (8 bits with per-component scale) or coded "
                    "(steps from quality=, texels by 8×8 DCT, entropy-coded)"}
    assert codecs["mlvq"][1]["threshold"]["default"] == "3e-5"


def texel_queries(source, n, rng):
    """n random (texel centre, view, light) queries and the source's values there."""
    x = rng.integers(0, source.width, n)
    y = rng.integers(0, source.height, n)
    v = rng.integers(0, source.num_views, n)
    l = rng.integers(0, source.num_lights, n)
    uv = np.stack([(x + 0.5) / source.width, (y + 0.5) / source.height], axis=1)
    expected = np.array([source.image(int(v[k]), int(l[k]))[y[k], x[k]] for k in range(n)])
    return uv, source.lights[l], source.views[v], expected


def test_eval_at_the_samples_gives_the_source_back(source, package):
    m = bk.open_material(package)
    assert (m.width, m.height) == (8, 8)
    uv, wi, wo, expected = texel_queries(source, 200, np.random.default_rng(7))
    got = m.eval(uv, wi, wo)
    assert got.dtype == np.float32 and got.shape == (200, 3)
    # Full rank in half floats: the rounding of the halves only.
    np.testing.assert_allclose(got, expected, rtol=2e-2, atol=2e-3)


def test_eval_is_the_same_in_any_batch_and_any_dtype(package):
    m = bk.open_material(package)
    rng = np.random.default_rng(11)
    n = 10000  # more than one task of the parallel batch
    uv = rng.random((n, 2))
    wi = rng.normal(size=(n, 3)); wi[:, 2] = np.abs(wi[:, 2])
    wo = rng.normal(size=(n, 3)); wo[:, 2] = np.abs(wo[:, 2])
    whole = m.eval(uv, wi, wo)
    for k in (0, 4095, 4096, 9999):
        np.testing.assert_array_equal(m.eval(uv[k:k + 1], wi[k:k + 1], wo[k:k + 1]), whole[k:k + 1])
    # float32 and lists are converted; the values are those of the float64 arrays' rounding.
    np.testing.assert_array_equal(m.eval(uv.astype(np.float32).astype(np.float64), wi, wo),
                                  m.eval(uv.astype(np.float32), wi, wo))
    assert m.eval([[0.5, 0.5]], [[0, 0, 1]], [[0, 0, 1]]).shape == (1, 3)


def test_bad_arguments_name_themselves(package):
    m = bk.open_material(package)
    ok2, ok3 = np.zeros((4, 2)), np.tile([0.0, 0.0, 1.0], (4, 1))
    with pytest.raises(ValueError, match=r"wi: expected shape \(N, 3\)"):
        m.eval(ok2, ok2, ok3)
    with pytest.raises(ValueError, match="wo: 3 rows, expected 4"):
        m.eval(ok2, ok3, ok3[:3])
    bad = ok3.copy(); bad[2, 0] = math.nan
    with pytest.raises(ValueError, match="wo: row 2 holds a value that is not finite"):
        m.eval(ok2, ok3, bad)
    with pytest.raises(ValueError, match="uv: expected an array of numbers"):
        m.eval("not numbers", ok3, ok3)


def test_sample_draws_by_its_pdf_and_reports_the_value(package):
    m = bk.open_material(package)
    rng = np.random.default_rng(5)
    n = 2000
    uv = np.tile([0.3, 0.6], (n, 1))
    wo = np.tile([0.3, 0.1, 0.9], (n, 1))
    xi = rng.random((n, 2))
    wi, pdf, value = m.sample(uv, wo, xi)
    assert wi.shape == (n, 3) and pdf.shape == (n,) and value.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-9)
    assert (wi[:, 2] >= 0).all() and (pdf > 0).all()
    np.testing.assert_allclose(value, m.eval(uv, wi, wo), rtol=1e-4, atol=1e-6)
    # pdf() gives the density each drawn direction was drawn with.
    np.testing.assert_allclose(m.pdf(uv, wo, wi), pdf, rtol=1e-5)
    # E[value / pdf] = π · albedo per channel: the estimate from these draws (a fixed seed: the
    # same numbers every run, no timing involved) lies within 5 of its standard errors of it.
    estimate = value / pdf[:, None]
    albedo = m.albedo(uv[:1], wo[:1])[0]
    mean, se = estimate.mean(axis=0), estimate.std(axis=0) / math.sqrt(n)
    assert (np.abs(mean - math.pi * albedo) < 5 * se + 1e-3).all(), (mean, math.pi * albedo, se)


def test_quality_measures_what_btf_quality_measures(source, package):
    same = bk.quality(source, source, metrics=["rmse", "de2000"])
    assert same["rmse"] == 0 and same["psnr"] is None and same["de2000"]["max"] == 0
    assert (same["width"], same["views"], same["images"]) == (8, 81, 81 * 81)
    full = bk.quality(source, package, metrics="rmse,ssim")
    assert 0 < full["rmse"] < 2e-3 and full["ssim"]["luminance"] > 0.999
    assert "lab_mae" not in full
    # The package's own path and its decoded material give the same numbers.
    again = bk.quality(source, bk.open_material(package) and str(package), metrics="rmse")
    assert again["rmse"] == full["rmse"]
    with pytest.raises(bk.Error, match="unknown metric 'psnr'"):
        bk.quality(source, source, metrics="psnr")


def test_eval_sample_reads_exact_samples(source, package):
    m = bk.open_material(package)
    np.testing.assert_allclose(m.views, source.views, atol=1e-12)
    rng = np.random.default_rng(9)
    idx = np.stack([rng.integers(0, 8, 100), rng.integers(0, 8, 100),
                    rng.integers(0, 81, 100), rng.integers(0, 81, 100)], axis=1)
    got = m.eval_sample(idx)
    expected = np.array([source.image(int(v), int(l))[y, x] for x, y, v, l in idx])
    np.testing.assert_allclose(got, expected, rtol=2e-2, atol=2e-3)
    with pytest.raises(ValueError, match="row 1: view 81 is out of range"):
        m.eval_sample([[0, 0, 0, 0], [0, 0, 81, 0]])


def test_the_type_stubs_describe_the_module():
    import ast
    import inspect
    import pathlib
    stub = pathlib.Path(bk.__file__).with_name("__init__.pyi")
    assert stub.exists() and stub.with_name("py.typed").exists()
    tree = ast.parse(stub.read_text())
    top = {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    assert set(bk.__all__) == set(top), set(bk.__all__) ^ set(top)
    for name in ("Source", "Material"):
        declared = {n.name for n in top[name].body if isinstance(n, ast.FunctionDef)}
        public = {a for a in dir(getattr(bk, name)) if not a.startswith("_")}
        assert declared == public, (name, declared ^ public)
    # The pure-Python functions' parameters are the stubs' (the native ones have no signature).
    for name, node in top.items():
        obj = getattr(bk, name)
        if isinstance(node, ast.FunctionDef) and inspect.isfunction(obj):
            stub_args = [a.arg for a in node.args.args + node.args.kwonlyargs]
            real = [p.name for p in inspect.signature(obj).parameters.values()
                    if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)]
            assert stub_args == real, name


def test_help_of_compress_lists_every_codec_parameter():
    doc = bk.compress.__doc__
    for name, (_, params) in bk.codecs().items():
        assert f"\n{name}: " in doc
        for key, p in params.items():
            assert f"    {key.replace('-', '_')}={p['default']}" in doc, (name, key)
