"""An estimator written in Python: registered with its spec, run by reconstruct and by the
study beside the built-in ones, in results.json and in the viewer."""

from __future__ import annotations

import json

import numpy as np
import pytest

import cvtrace
from conftest import CORNELL, CORNELL_REF


class Blend:
    """The PT and CRN means mixed with a fixed weight, optionally box-blurred."""

    def __init__(self, weight, radius, mode):
        self.weight, self.radius, self.mode = weight, radius, mode

    def reconstruct(self, streams):
        img = self.weight * streams.pt + (1 - self.weight) * streams.crn
        if self.mode == "blur" and self.radius > 0:
            r = self.radius
            padded = np.pad(img, ((r, r), (r, r), (0, 0)), mode="edge")
            img = sum(padded[dy : dy + img.shape[0], dx : dx + img.shape[1]] for dy in range(2 * r + 1) for dx in range(2 * r + 1)) / (2 * r + 1) ** 2
        return img, {"weight": self.weight, "batches": streams.batches}


PARAMS = [
    cvtrace.Param("weight", "float", 0.5, "Weight of the PT mean.", min=0, max=1),
    cvtrace.Param("radius", "int", 0, "Blur radius in pixels.", min=0, max=4),
    cvtrace.Param("mode", "choice", "plain", "What to do after blending.", choices=["plain", "blur"]),
]


@pytest.fixture
def blend():
    cvtrace.register(Blend, name="py-blend", label="Blend (Python)", short="Blend", summary="A blend of the two means.", colour="#ff8800", params=PARAMS, batches=(2, 64), variants=[("py-blend-blur", "Blend, blurred", {"mode": "blur", "radius": 1})])
    yield
    cvtrace.unregister("py-blend")


def test_registered_estimator_is_listed_and_runs(small, blend):
    spec = next(e for e in cvtrace.estimators() if e["name"] == "py-blend")
    assert spec["python"] and spec["label"] == "Blend (Python)" and spec["colour"] == "#ff8800" and spec["batches"] == "2..64"
    assert [p["name"] for p in spec["params"]] == ["weight", "radius", "mode"]
    assert spec["params"][0]["range"] == "number, ≥ 0 and ≤ 1"
    assert "py-blend.weight = 0.5" in cvtrace.estimator_help("py-blend")
    img = cvtrace.reconstruct(small, "py-blend")
    assert np.allclose(img, 0.5 * small.pt + 0.5 * small.crn)
    r = cvtrace.reconstruct(small, "py-blend", details=True, weight=1.0)
    assert np.array_equal(r.image, small.pt) and r.diagnostics == {"weight": 1.0, "batches": 4}
    assert r.settings == {"weight": "1", "radius": "0", "mode": "plain"}
    with pytest.raises(cvtrace.Error, match=r"`py-blend.weight` .*must be finite, ≥ 0 and ≤ 1|py-blend.weight"):
        cvtrace.reconstruct(small, "py-blend", weight=2)
    with pytest.raises(cvtrace.Error, match="expected one of: plain, blur"):
        cvtrace.reconstruct(small, "py-blend", mode="sharpen")
    one = cvtrace.Streams.from_arrays(np.ones((1, 4, 4, 3)), np.ones((1, 4, 4, 3)))
    with pytest.raises(cvtrace.Error, match="py-blend"):
        cvtrace.reconstruct(one, "py-blend")


def test_a_python_exception_comes_back_as_itself(small):
    class Broken:
        def reconstruct(self, streams):
            raise ZeroDivisionError("on purpose")

    class WrongSize:
        def reconstruct(self, streams):
            return np.zeros((3, 3, 3))

    cvtrace.register(Broken, name="py-broken")
    cvtrace.register(WrongSize, name="py-wrong-size")
    try:
        with pytest.raises(ZeroDivisionError, match="on purpose"):
            cvtrace.reconstruct(small, "py-broken")
        with pytest.raises(ValueError, match="3x3, but the streams are 32x32"):
            cvtrace.reconstruct(small, "py-wrong-size")
    finally:
        cvtrace.unregister("py-broken")
        cvtrace.unregister("py-wrong-size")


def test_bad_registrations_are_refused():
    with pytest.raises(cvtrace.Error, match="not a usable name"):
        cvtrace.register(Blend, name="Py Blend", params=PARAMS)
    with pytest.raises(cvtrace.Error, match="registered already"):
        cvtrace.register(Blend, name="ours", params=PARAMS)
    with pytest.raises(cvtrace.Error, match="default"):
        cvtrace.register(Blend, name="py-bad-default", params=[cvtrace.Param("weight", "float", 3, min=0, max=1)])
    with pytest.raises(ValueError, match="kind"):
        cvtrace.register(Blend, name="py-bad-kind", params=[cvtrace.Param("weight", "complex", 0)])
    with pytest.raises(TypeError, match="callable"):
        cvtrace.register(42, name="py-not-callable")
    with pytest.raises(ValueError, match="no estimator of that name"):
        cvtrace.unregister("ours")
    assert not any(e["name"].startswith("py-") for e in cvtrace.estimators())


def test_study_runs_the_python_estimator_beside_the_built_ins(blend, tmp_path):
    out = tmp_path / "study"
    reference = tmp_path / "ref.exr"
    results = cvtrace.study(
        CORNELL,
        reference=reference,
        reference_spp=64,
        output=out,
        spp=[4, 8],
        seeds=2,
        width=24,
        height=24,
        methods="pt,average,ours,py-blend",
        params={"py-blend.weight": 0.25, "ours": {"k": 16}},
        ablations=True,
        headline=["ours/pt2n", "py-blend/pt2n"],
    )
    assert results == json.loads((out / "results.json").read_text())
    scene = results["scenes"][0]
    by_name = {m["name"]: m for m in scene["methods"]}
    assert set(by_name) >= {"pt", "average", "ours", "py-blend", "pt2n", "py-blend-blur"}
    blend_result = by_name["py-blend"]
    assert blend_result["label"] == "Blend (Python)" and blend_result["colour"] == "#ff8800"
    assert ["weight", "0.25"] in blend_result["settings"] and by_name["ours"]["settings"][1] == ["k", "16"]
    assert blend_result["relmse_mean"] > 0 and len(blend_result["relmse_per_seed"]) == 2
    assert dict(blend_result["diagnostics"])["weight"] == 0.25
    assert by_name["py-blend-blur"]["ablation"] and by_name["py-blend-blur"]["base"] == "py-blend"
    assert (out / "py-blend.png").is_file() and (out / "py-blend.values.exr").is_file()
    # The viewer shows it.
    index = cvtrace.report(out, tmp_path / "report")
    assert index.name == "index.html"
    data = "".join(p.read_text(errors="replace") for p in (tmp_path / "report").rglob("*.js"))
    assert "Blend (Python)" in data and "py-blend" in data
    # A second run reuses the renders and gives the same numbers.
    again = cvtrace.study(CORNELL, reference=reference, output=out, spp=[4, 8], seeds=2, width=24, height=24,
                          methods="pt,average,ours,py-blend", params={"py-blend.weight": 0.25, "ours": {"k": 16}},
                          ablations=True, headline=["ours/pt2n", "py-blend/pt2n"])
    assert [m["relmse_mean"] for m in again["scenes"][0]["methods"]] == [m["relmse_mean"] for m in scene["methods"]]


def test_study_checks_come_first(tmp_path):
    out = tmp_path / "s"
    with pytest.raises(cvtrace.Error, match="scene file not found"):
        cvtrace.study(tmp_path / "none.gltf", reference=tmp_path / "r.exr", output=out)
    with pytest.raises(cvtrace.Error, match="seeds=0"):
        cvtrace.study(CORNELL, reference=CORNELL_REF, output=out, seeds=0)
    with pytest.raises(cvtrace.Error, match="does not divide"):
        cvtrace.study(CORNELL, reference=CORNELL_REF, output=out, spp=[6], batches=4)
    with pytest.raises(cvtrace.Error, match="not a reference of this study's image"):
        cvtrace.study(CORNELL, reference=CORNELL_REF, output=out, spp=[4], width=16)
    with pytest.raises(cvtrace.Error, match="unknown estimator"):
        cvtrace.study(CORNELL, reference=CORNELL_REF, output=out, spp=[4], methods="nope")
    assert not out.exists()
