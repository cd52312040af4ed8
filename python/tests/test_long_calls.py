# SPDX-License-Identifier: MIT
"""decompress, render, several materials in one package, and what every long call shares:
progress callbacks, cancellation and Ctrl-C, with nothing left behind."""
import os
import signal

import numpy as np
import pytest

import btfkit as bk


def test_decompress_writes_what_the_package_decodes_to(source, package, tmp_path):
    out = tmp_path / "decoded.h5"
    bk.decompress(package, out, half=False)
    decoded = bk.open(out)
    assert (decoded.width, decoded.height, decoded.num_views) == (8, 8, 81)
    m = bk.open_material(package)
    # HDF5 in float32 holds the decoded values exactly: eval_sample at every texel of one image.
    view, light = 4, 9
    ys, xs = np.mgrid[0:8, 0:8]
    idx = np.stack([xs.ravel(), ys.ravel(), np.full(64, view), np.full(64, light)], axis=1)
    np.testing.assert_array_equal(decoded.image(view, light).reshape(-1, 3), m.eval_sample(idx))
    # A UTIA image set in a new folder; an extension it does not know is refused up front.
    bk.decompress(package, tmp_path / "utia", format="exr")
    assert (tmp_path / "utia").is_dir()
    with pytest.raises(bk.Error, match="unknown output type '.png'"):
        bk.decompress(package, tmp_path / "x.png")
    with pytest.raises(ValueError, match="deflate"):
        bk.decompress(package, tmp_path / "y.h5", deflate=12)
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "y.h5").exists()


def scene(material):
    return {
        "camera": {"position": [0, 1.2, 1.2], "look_at": [0, 0, 0], "fov": 40, "width": 24,
                   "height": 16},
        "render": {"integrator": "direct", "spp": 2},
        "objects": [{"shape": "plane", "width": 2, "depth": 2,
                     "material": {"type": "btf", "file": str(material)}}],
        "lights": [{"type": "directional", "direction": [-1, 0.3, -0.5], "irradiance": 3}],
    }


def test_render_gives_linear_radiance_and_takes_the_command_line_overrides(package, tmp_path):
    image = bk.render(scene(package))
    assert image.dtype == np.float32 and image.shape == (16, 24, 3)
    assert np.isfinite(image).all() and image.mean() > 0.01
    # The same seed gives the same picture; size and seed override the scene's.
    np.testing.assert_array_equal(bk.render(scene(package)), image)
    assert bk.render(scene(package), size=(12, 8)).shape == (8, 12, 3)
    assert not np.array_equal(bk.render(scene(package), seed=7), image)
    # A scene file renders like its dict, and material= replaces the scene's own file.
    path = tmp_path / "scene.json"
    path.write_text(__import__("json").dumps(scene(tmp_path / "absent.btfpkg")))
    np.testing.assert_array_equal(bk.render(path, material=package), image)
    with pytest.raises(bk.Error, match="absent.btfpkg"):
        bk.render(path)
    with pytest.raises(bk.Error, match="max-depth applies to the path integrator"):
        bk.render(scene(package), max_depth=3)
    with pytest.raises(ValueError, match="size"):
        bk.render(scene(package), size=(0, 4))


def test_several_sources_share_one_mlvq_package(tmp_path):
    a = bk.synth("leather", 8, seed=1)
    b = bk.synth("woven_fabric", 8, seed=2)
    out = tmp_path / "shared.btfpkg"
    grid = dict(n_alpha=5, n_beta=5, n_theta_v=3, n_phi_v=4)
    bk.compress([a, b], out, codec="mlvq", **grid)
    materials = bk.open_materials(out)
    assert len(materials) == 2
    assert bk.open_material(out).width == materials[0].width  # the first
    with pytest.raises(bk.Error, match="codec fmf compresses one input"):
        bk.compress([a, b], tmp_path / "no.btfpkg", codec="fmf")
    assert not (tmp_path / "no.btfpkg").exists()


def test_progress_is_reported_on_the_calling_thread(source, tmp_path):
    seen = []
    bk.compress(source, tmp_path / "p.btfpkg", codec="fmf", components=4,
                progress=lambda stage, done, total: seen.append((stage, done, total)))
    assert seen, "no progress reported"
    assert all(isinstance(s, str) and 0 <= d and (t == 0 or d <= t) for s, d, t in seen)
    with pytest.raises(ValueError, match="progress"):
        bk.compress(source, tmp_path / "q.btfpkg", progress=3)


class Stop(Exception):
    pass


def test_an_exception_in_the_callback_cancels_and_leaves_nothing(source, tmp_path):
    out = tmp_path / "cancelled.btfpkg"

    def stop(stage, done, total):
        raise Stop(stage)

    with pytest.raises(Stop):
        bk.compress(source, out, codec="fmf", components=4, progress=stop)
    assert not out.exists()
    assert [p for p in tmp_path.iterdir()] == []  # no temporary file either


def test_ctrl_c_interrupts_a_long_call_and_leaves_nothing(source, tmp_path):
    out = tmp_path / "interrupted.h5"

    def press_ctrl_c(stage, done, total):
        os.kill(os.getpid(), signal.SIGINT)  # what the terminal sends

    with pytest.raises(KeyboardInterrupt):
        bk.quality(source, source, metrics=["rmse"], progress=press_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        bk.compress(source, tmp_path / "i.btfpkg", codec="fmf", components=4,
                    progress=press_ctrl_c)
    assert [p for p in tmp_path.iterdir()] == []
