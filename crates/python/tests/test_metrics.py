"""The metrics compare reports, and plain images in and out."""

from __future__ import annotations

import numpy as np
import pytest

import cvtrace
from conftest import CORNELL_REF, same_bits


def numpy_relmse(x, r):
    x, r = np.asarray(x, np.float64), np.asarray(r, np.float64)
    return float(np.mean((x - r) ** 2 / (r.mean(axis=2, keepdims=True) ** 2 + 0.01)))


def test_relmse_and_mse_follow_their_definitions():
    rng = np.random.default_rng(2)
    r = rng.random((6, 5, 3), dtype=np.float32)
    x = r + rng.normal(0, 0.1, r.shape).astype(np.float32)
    assert cvtrace.relmse(x, r) == pytest.approx(numpy_relmse(x, r), rel=1e-6)
    assert cvtrace.mse(x, r) == pytest.approx(float(np.mean((x.astype(np.float64) - r) ** 2)), rel=1e-6)
    m = cvtrace.relmse_map(x, r)
    assert m.shape == (6, 5) and m.dtype == np.float32 and m.mean() == pytest.approx(cvtrace.relmse(x, r), rel=1e-5)
    assert cvtrace.relmse(r, r) == 0.0 and cvtrace.relmse(r.tolist(), r) == 0.0


def test_flip_and_the_compare_set(tmp_path):
    ref = cvtrace.read_image(CORNELL_REF)
    noisy = ref + np.random.default_rng(3).normal(0, 0.05, ref.shape).astype(np.float32)
    assert cvtrace.flip(ref, ref) == 0.0
    mean, fmap = cvtrace.flip(noisy, ref, map=True)
    assert 0 < mean < 1 and fmap.shape == ref.shape[:2] and fmap.mean() == pytest.approx(mean, rel=1e-4)
    m = cvtrace.metrics(noisy, ref)
    assert m == {"relmse": cvtrace.relmse(noisy, ref), "mse": cvtrace.mse(noisy, ref), "flip": mean}
    # cvtrace compare on files gives the same numbers.
    path = tmp_path / "noisy.exr"
    cvtrace.write_image(path, noisy)
    results = cvtrace.compare(CORNELL_REF, [path])
    method = results["scenes"][0]["methods"][0]
    assert method["name"] == "noisy" and method["relmse_mean"] == m["relmse"] and method["flip_mean"] == mean


def test_images_round_trip_and_bad_input_is_named(tmp_path):
    img = np.random.default_rng(4).random((7, 9, 3), dtype=np.float32)
    cvtrace.write_image(tmp_path / "a.exr", img)
    assert same_bits(cvtrace.read_image(tmp_path / "a.exr"), img)
    cvtrace.write_image(tmp_path / "a.png", img, exposure=1.0)
    assert (tmp_path / "a.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(cvtrace.Error, match="exists"):
        cvtrace.write_image(tmp_path / "a.exr", img)
    with pytest.raises(ValueError, match=r"x: expected an array of shape \(H, W, 3\), got \(7, 9\)"):
        cvtrace.relmse(img[..., 0], img)
    with pytest.raises(cvtrace.Error, match=r"x is 9x6.*ref is 9x7|x.*9x6"):
        cvtrace.relmse(img[:6], img)
    bad = img.copy()
    bad[2, 3, 1] = np.inf
    with pytest.raises(cvtrace.Error, match="x"):
        cvtrace.relmse(bad, img)
    with pytest.raises(cvtrace.Error, match="no such file"):
        cvtrace.read_image(tmp_path / "none.exr")
    with pytest.raises(cvtrace.Error, match=r"\.exr"):
        cvtrace.write_image(tmp_path / "a.tif", img)


def test_the_readme_five_lines(capsys, monkeypatch):
    """The README's first Python example, as written, from the repository root."""
    from conftest import ROOT

    text = (ROOT / "README.md").read_text()
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    assert len(code.strip().splitlines()) == 5
    monkeypatch.chdir(ROOT)
    exec(compile(code, "README.md", "exec"), {})
    relmse = float(capsys.readouterr().out.strip())
    assert 0 < relmse < 0.05
