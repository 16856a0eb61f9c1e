"""Type stubs of the cvtrace package (the extension module `cvtrace._cvtrace` and its Python layer)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Callable, Literal, Sequence, overload

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = str | os.PathLike[str]
ArrayLike = npt.ArrayLike
Image = npt.NDArray[np.float32]
"""An (H, W, 3) float32, C-contiguous array."""

class Error(Exception):
    """An error of cvtrace, with the message the `cvtrace` command line prints."""

class Streams:
    """The paired PT and CRN renders of one image, read-only (see `render`, `Streams.read`,
    `Streams.from_arrays`)."""

    @property
    def pt(self) -> Image:
        """The PT stream's mean, (H, W, 3)."""
    @property
    def crn(self) -> Image:
        """The CRN stream's mean, (H, W, 3)."""
    @property
    def pt_batches(self) -> npt.NDArray[np.float32]:
        """The PT stream's batch means, (B, H, W, 3)."""
    @property
    def crn_batches(self) -> npt.NDArray[np.float32]:
        """The CRN stream's batch means, (B, H, W, 3)."""
    @property
    def albedo(self) -> Image | None: ...
    @property
    def normal(self) -> Image | None: ...
    @property
    def depth(self) -> npt.NDArray[np.float32] | None:
        """First-hit depth, (H, W)."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def batches(self) -> int: ...
    @property
    def spp(self) -> int:
        """Samples per pixel of each stream (0: unknown)."""
    @property
    def seed(self) -> int: ...
    @property
    def max_depth(self) -> int: ...
    @property
    def scene(self) -> str: ...
    @property
    def version(self) -> str: ...
    @property
    def non_finite_samples(self) -> int: ...
    @property
    def origin(self) -> str: ...
    @property
    def settings(self) -> dict[str, str]: ...
    @property
    def provenance(self) -> dict[str, str] | None:
        """size, seed, max depth, rr depth, scene hash, camera, traversal, spp, batches, version."""
    @staticmethod
    def read(path: PathLike) -> Streams:
        """Reads a stream file (or IDUW's input layout)."""
    def write(self, path: PathLike, overwrite: bool = False) -> None:
        """Writes the stream file atomically; `Streams.read` gives it back bit for bit."""
    @staticmethod
    def from_arrays(
        pt_batches: ArrayLike,
        crn_batches: ArrayLike,
        *,
        albedo: ArrayLike | None = None,
        normal: ArrayLike | None = None,
        depth: ArrayLike | None = None,
        spp: int = 0,
        seed: int = 0,
        max_depth: int = -1,
        scene: str = "",
        pt: ArrayLike | None = None,
        crn: ArrayLike | None = None,
    ) -> Streams:
        """Streams from any renderer's batch means, (B, H, W, 3) each, checked as a stream file is."""

class Reconstruction:
    """What one estimator made (`reconstruct(..., details=True)`)."""

    method: str
    image: Image
    variance: Image | None
    aovs: dict[str, Image]
    diagnostics: dict[str, float | int | str]
    settings: dict[str, str]
    seconds: float
    def __array__(self, dtype: Any = None, copy: bool | None = None) -> Image: ...

def render(
    scene: PathLike,
    spp: int | None = None,
    batches: int | None = None,
    seed: int = 0,
    width: int | None = None,
    height: int | None = None,
    threads: int | None = None,
    *,
    output: PathLike | None = None,
    overwrite: bool = False,
    camera: tuple[Sequence[float], Sequence[float], float] | None = None,
    traversal: Literal["fast", "robust"] = "fast",
    **defines: Any,
) -> Streams:
    """Renders the paired PT and CRN streams of a glTF scene, as `cvtrace render` does."""

def render_reference(
    scene: PathLike,
    spp: int | None = None,
    seed: int = 0,
    width: int | None = None,
    height: int | None = None,
    threads: int | None = None,
    *,
    output: PathLike | None = None,
    overwrite: bool = False,
    camera: tuple[Sequence[float], Sequence[float], float] | None = None,
    traversal: Literal["fast", "robust"] = "fast",
    **defines: Any,
) -> Image:
    """Renders a plain path-traced image (a reference, or PT at equal samples)."""

@overload
def reconstruct(
    streams: Streams | PathLike,
    method: str = "ours",
    *,
    reference: ArrayLike | None = None,
    pt2n: ArrayLike | None = None,
    details: Literal[False] = False,
    threads: int | None = None,
    **params: Any,
) -> Image: ...
@overload
def reconstruct(
    streams: Streams | PathLike,
    method: str = "ours",
    *,
    reference: ArrayLike | None = None,
    pt2n: ArrayLike | None = None,
    details: Literal[True],
    threads: int | None = None,
    **params: Any,
) -> Reconstruction: ...
def estimators() -> list[dict[str, Any]]:
    """Every registered estimator with its spec (parameters, defaults, ranges, docs)."""

def estimator_help(name: str) -> str:
    """An estimator's spec as `cvtrace reconstruct --help-method NAME` prints it."""

@dataclass(frozen=True)
class Param:
    name: str
    kind: str
    default: Any
    doc: str = ""
    min: float | None = None
    max: float | None = None
    above: bool = False
    choices: Sequence[str] | None = None

def register(
    factory: Callable[..., Any],
    *,
    name: str,
    label: str | None = None,
    short: str | None = None,
    summary: str = "",
    colour: str | tuple[int, int, int] | None = None,
    samples: Literal["both", "one"] = "both",
    params: Sequence[Param | dict[str, Any]] | None = None,
    batches: tuple[int, int] | tuple[Literal["multiple"], int] | None = None,
    features: bool = False,
    spp: bool = False,
    variants: Sequence[tuple[str, str, dict[str, Any]]] | None = None,
) -> None:
    """Registers an estimator written in Python (a factory of objects with `reconstruct(streams)`)."""

def estimator(*, name: str, **spec: Any) -> Callable[[type], type]:
    """Class decorator form of `register`."""

def unregister(name: str) -> None: ...
def relmse(x: ArrayLike, ref: ArrayLike) -> float:
    """relMSE: mean of (x - r)^2 / (mean(r)^2 + 0.01) over pixels and channels."""

def mse(x: ArrayLike, ref: ArrayLike) -> float: ...
def relmse_map(x: ArrayLike, ref: ArrayLike) -> npt.NDArray[np.float32]: ...
@overload
def flip(x: ArrayLike, ref: ArrayLike, *, map: Literal[False] = False) -> float: ...
@overload
def flip(x: ArrayLike, ref: ArrayLike, *, map: Literal[True]) -> tuple[float, npt.NDArray[np.float32]]: ...
def metrics(x: ArrayLike, ref: ArrayLike) -> dict[str, float]:
    """relmse, mse and flip, as `cvtrace compare` reports them."""

def compare(reference: PathLike, images: Sequence[PathLike]) -> dict[str, Any]: ...
def read_image(path: PathLike) -> Image: ...
def write_image(path: PathLike, image: ArrayLike, *, overwrite: bool = False, exposure: float = 0.0) -> None: ...
def study(
    scene: PathLike,
    *,
    reference: PathLike,
    output: PathLike,
    spp: int | Sequence[int] | None = None,
    seeds: int = 8,
    seed: int = 1,
    batches: int | None = None,
    reference_spp: int | None = None,
    methods: str | Sequence[str] | None = None,
    params: dict[str, Any] | None = None,
    ablations: bool = False,
    name: str | None = None,
    headline: Sequence[str] | None = None,
    width: int | None = None,
    height: int | None = None,
    camera: tuple[Sequence[float], Sequence[float], float] | None = None,
    traversal: Literal["fast", "robust"] = "fast",
    threads: int | None = None,
    **defines: Any,
) -> dict[str, Any]:
    """Runs the paper's protocol as `cvtrace study` does; returns results.json as a dict."""

def report(study: PathLike, output: PathLike, *, title: str = "cvtrace", overwrite: bool = False) -> os.PathLike[str]:
    """Writes the HTML viewer of a study folder; returns its index.html."""
