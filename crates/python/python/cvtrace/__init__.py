"""cvtrace from Python: render paired PT/CRN sample streams, reconstruct images from them with
cvtrace's estimators (or your own, written in Python), and score them, all on numpy arrays.

    import cvtrace
    s = cvtrace.render("scenes/cornell-box/scene.gltf", spp=32, seed=1)   # Streams: pt, crn, batches, features
    img = cvtrace.reconstruct(s, "ours")                                   # (H, W, 3) float32
    ref = cvtrace.read_image("scenes/cornell-box/scene.ref.exr")
    print(cvtrace.relmse(img, ref))

Images are float32, C-contiguous (H, W, C) numpy arrays; anything array-like is accepted as
input. Every function is the library behind one command of the ``cvtrace`` program, with its
checks and messages: errors raise ``cvtrace.Error``. Long calls release the GIL, and Ctrl-C
raises ``KeyboardInterrupt`` without leaving half-written files.

Streams of another renderer: ``cvtrace.Streams.from_arrays(pt_batches, crn_batches, spp=...)``.
An estimator of your own: ``cvtrace.register(MyEstimator, name=..., params=[cvtrace.Param(...)])``
(or the ``@cvtrace.estimator(...)`` decorator); it then runs in ``reconstruct`` and ``study``
beside the built-in ones.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from ._cvtrace import (
    Error,
    Reconstruction,
    Streams,
    __version__,
    estimator_help,
    estimators,
    flip,
    metrics,
    mse,
    read_image,
    reconstruct,
    register,
    relmse,
    relmse_map,
    render,
    render_reference,
    report,
    unregister,
    write_image,
)
from . import _cvtrace

__all__ = [
    "Error",
    "Param",
    "Reconstruction",
    "Streams",
    "__version__",
    "compare",
    "estimator",
    "estimator_help",
    "estimators",
    "flip",
    "metrics",
    "mse",
    "read_image",
    "reconstruct",
    "register",
    "relmse",
    "relmse_map",
    "render",
    "render_reference",
    "report",
    "study",
    "unregister",
    "write_image",
]


@dataclass(frozen=True)
class Param:
    """A parameter of an estimator written in Python (see ``register``).

    ``kind`` is ``"int"``, ``"float"``, ``"bool"``, ``"choice"`` (with ``choices``),
    ``"floats"`` (a list of numbers) or ``"auto-float"`` (``"auto"`` or a number, passed to the
    factory as None or a float). ``min``/``max`` bound numbers (``above=True`` excludes
    ``min``); values out of range are refused with the message cvtrace gives for its own.
    """

    name: str
    kind: str
    default: Any
    doc: str = ""
    min: float | None = None
    max: float | None = None
    above: bool = False
    choices: Sequence[str] | None = None


def estimator(*, name: str, **spec: Any) -> Callable[[type], type]:
    """Class decorator: ``register(cls, name=name, **spec)``, returning the class."""

    def wrap(cls: type) -> type:
        register(cls, name=name, **spec)
        return cls

    return wrap


def study(scene: str | os.PathLike[str], **kwargs: Any) -> dict[str, Any]:
    """Runs the paper's protocol on ``scene`` as ``cvtrace study`` does and returns its
    ``results.json`` as a dict (``{"schema_version", "cvtrace_version", "scenes": [...]}``,
    each scene with its ``methods``: relMSE mean and standard error, bias², variance, FLIP,
    times, settings, diagnostics, labels and colours).

    Keyword arguments: ``reference`` (EXR; rendered when missing), ``output`` (the study
    folder), ``spp`` (one value or a list), ``seeds``, ``seed``, ``batches``,
    ``reference_spp``, ``methods`` (default: every registered estimator, those registered
    from Python included), ``params`` (``{"ours.k": 16}``), ``ablations``, ``name``,
    ``headline``, and the render's ``width``, ``height``, ``camera``, ``traversal``,
    ``threads`` and ``**defines``. See ``help(cvtrace._cvtrace.study_json)``.
    """
    return json.loads(_cvtrace.study_json(scene, **kwargs))


def compare(reference: str | os.PathLike[str], images: Sequence[str | os.PathLike[str]]) -> dict[str, Any]:
    """``cvtrace compare``: scores EXR files against a reference EXR; the results as a dict in
    the study's schema (relMSE, MSE and HDR-FLIP per image, the method named by each file's
    ``cvtrace.method`` attribute or its name)."""
    return json.loads(_cvtrace.compare_json(reference, list(images)))
