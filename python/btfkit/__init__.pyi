# SPDX-License-Identifier: MIT
# Type stubs of the btfkit module (the native part is _btfkit). Arrays are NumPy arrays; inputs
# of any real dtype are converted, outputs are float32 values and float64 directions and pdfs.
from os import PathLike
from typing import Any, Callable, Iterator, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, bytes, PathLike[str]]
_Array = npt.ArrayLike
_Progress = Optional[Callable[[str, int, int], None]]

__version__: str
"""btfkit's version, "MAJOR.MINOR.PATCH" (the same as `btf --version` and the packages' writer)."""

class Error(Exception):
    """A btfkit error: the same one-line message as the btf command prints."""

class Source:
    """A BTF on disk or synthesized, read one image at a time."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def num_views(self) -> int: ...
    @property
    def num_lights(self) -> int: ...
    @property
    def views(self) -> npt.NDArray[np.float64]: ...
    @property
    def lights(self) -> npt.NDArray[np.float64]: ...
    @property
    def view_degrees(self) -> npt.NDArray[np.float64]: ...
    @property
    def light_degrees(self) -> npt.NDArray[np.float64]: ...
    @property
    def format(self) -> str: ...
    @property
    def hdr(self) -> bool: ...
    def image(self, view: int, light: int) -> npt.NDArray[np.float32]: ...

class Material:
    """A random-access BTF material (a package, or a UBO2014 file)."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def views(self) -> npt.NDArray[np.float64]: ...
    @property
    def lights(self) -> npt.NDArray[np.float64]: ...
    def eval(self, uv: _Array, wi: _Array, wo: _Array) -> npt.NDArray[np.float32]: ...
    def sample(
        self, uv: _Array, wo: _Array, xi: _Array
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float32]]: ...
    def pdf(self, uv: _Array, wo: _Array, wi: _Array) -> npt.NDArray[np.float64]: ...
    def albedo(self, uv: _Array, wo: _Array) -> npt.NDArray[np.float32]: ...
    def eval_sample(self, indices: _Array) -> npt.NDArray[np.float32]: ...

def open(path: _Path) -> Source: ...
def synth(preset: str, size: int, sampling: str = "ubo81", seed: int = 1) -> Source: ...
def presets() -> list[str]: ...
def codecs() -> dict[str, tuple[str, dict[str, dict[str, str]]]]: ...
def images(source: Source) -> Iterator[tuple[int, int, npt.NDArray[np.float32]]]: ...
def compress(
    source: Union[Source, _Path, Sequence[Union[Source, _Path]]],
    out: _Path,
    codec: str = "fmf",
    progress: _Progress = None,
    **params: Any,
) -> None: ...
def decompress(
    package: _Path,
    out: _Path,
    half: bool = True,
    deflate: int = 0,
    format: Optional[str] = None,
    progress: _Progress = None,
) -> None: ...
def open_material(path: _Path) -> Material: ...
def open_materials(path: _Path) -> list[Material]: ...
def quality(
    reference: Union[Source, _Path],
    test: Union[Source, _Path],
    metrics: Union[str, Sequence[str]] = ("rmse", "lab", "de2000", "ssim"),
    cos_weight: bool = False,
    peak: float = 0.0,
    progress: _Progress = None,
) -> dict[str, Any]: ...
def render(
    scene: Union[_Path, dict[str, Any]],
    spp: Optional[int] = None,
    size: Optional[tuple[int, int]] = None,
    seed: Optional[int] = None,
    integrator: Optional[str] = None,
    max_depth: Optional[int] = None,
    filter: Optional[str] = None,
    time: Optional[float] = None,
    material: Optional[_Path] = None,
    sampling: str = "material",
    progress: _Progress = None,
) -> npt.NDArray[np.float32]: ...
