# SPDX-License-Identifier: MIT
import pytest

import btfkit as bk


@pytest.fixture(scope="session")
def source():
    """A small synthetic material: 8 x 8 texels, 81 x 81 directions."""
    return bk.synth("woven_fabric", 8, seed=3)


@pytest.fixture(scope="session")
def package(source, tmp_path_factory):
    """fmf at full rank (64 components for 64 texels) in half floats: the source again, to
    within the halves' rounding."""
    out = tmp_path_factory.mktemp("pkg") / "full.btfpkg"
    bk.compress(source, out, codec="fmf", components=64, colour="rgb")
    return out
