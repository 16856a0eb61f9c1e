"""cvtrace.reconstruct and the estimator specs: every estimator, its options, the CLI's image
and messages, the GIL."""

from __future__ import annotations


import numpy as np
import pytest

import cvtrace
from conftest import CORNELL, SMALL, assert_releases_the_gil, cli_error, run_cli, same_bits

BUILT_IN = ["pt", "crn", "average", "iduw", "cv", "ours", "ivw"]


@pytest.fixture(scope="module")
def pt2n() -> np.ndarray:
    """The PT(2n) image of `small`'s scene: twice its samples per pixel, another seed."""
    return cvtrace.render_reference(CORNELL, spp=2 * SMALL["spp"], seed=11, width=SMALL["width"], height=SMALL["height"])


def test_every_estimator_runs(small, pt2n):
    names = [e["name"] for e in cvtrace.estimators()]
    assert names[: len(BUILT_IN)] == BUILT_IN and {"oidn", "pt2n-oidn", "blend"} <= set(names)
    for name in names:
        img = cvtrace.reconstruct(small, name, pt2n=pt2n)
        assert img.shape == (32, 32, 3) and img.dtype == np.float32 and img.flags.c_contiguous, name
        assert np.isfinite(img).all(), name
    assert same_bits(cvtrace.reconstruct(small, "pt"), small.pt)
    assert same_bits(cvtrace.reconstruct(small, "crn"), small.crn)


def test_details_give_the_variance_diagnostics_and_settings(small):
    r = cvtrace.reconstruct(small, "ours", details=True, k=16)
    assert isinstance(r, cvtrace.Reconstruction) and r.method == "ours"
    assert r.variance.shape == (32, 32, 3) and (r.variance >= 0).all() and "variance" in r.aovs
    assert r.settings["k"] == "16" and r.seconds > 0 and r.diagnostics
    assert same_bits(np.asarray(r), r.image) and same_bits(r.image, cvtrace.reconstruct(small, "ours", k=16))
    assert cvtrace.reconstruct(small, "iduw", details=True).variance is None
    assert "gamma" in cvtrace.reconstruct(small, "iduw", details=True).diagnostics


def test_parameters_take_python_values(small):
    a = cvtrace.reconstruct(small, "ours", k=9, search_window=7, shared_coefficients=True, ridge=0.01)
    b = cvtrace.reconstruct(small, "ours", k="9", search_window="7", shared_coefficients="true", ridge="0.01")
    assert same_bits(a, b) and not same_bits(a, cvtrace.reconstruct(small, "ours"))
    assert same_bits(
        cvtrace.reconstruct(small, "iduw", gammas=[0.1, 0.5], gamma=None),
        cvtrace.reconstruct(small, "iduw", gammas="0.1,0.5", gamma="auto"),
    )
    # Results are the same for any thread count.
    assert same_bits(cvtrace.reconstruct(small, "ours", threads=1), cvtrace.reconstruct(small, "ours", threads=2))


def test_oracle_errors_take_a_reference(small):
    ref = cvtrace.reconstruct(small, "average")
    img = cvtrace.reconstruct(small, "ours", errors="oracle", reference=ref)
    assert img.shape == (32, 32, 3)
    with pytest.raises(cvtrace.Error, match="needs a reference"):
        cvtrace.reconstruct(small, "ours", errors="oracle")
    with pytest.raises(cvtrace.Error, match="reference is 2x2"):
        cvtrace.reconstruct(small, "ours", errors="oracle", reference=np.ones((2, 2, 3)))


@pytest.mark.parametrize("method", ["ours", "iduw", "cv", "average"])
def test_bit_identical_to_the_cli(small, cli, tmp_path, method):
    streams = tmp_path / "s.streams.exr"
    small.write(streams)
    out = tmp_path / f"{method}.exr"
    done = run_cli(cli, "reconstruct", streams, "--method", method, "-o", out)
    assert done.returncode == 0, done.stderr
    from_cli = cvtrace.read_image(out)
    assert same_bits(cvtrace.reconstruct(cvtrace.Streams.read(streams), method), from_cli)
    assert same_bits(cvtrace.reconstruct(str(streams), method), from_cli)
    assert same_bits(cvtrace.reconstruct(small, method), from_cli)


@pytest.mark.parametrize("method", ["oidn", "pt2n-oidn", "blend"])
def test_the_denoisers_are_bit_identical_to_the_cli(small, pt2n, cli, tmp_path, method):
    streams, pt2n_file = tmp_path / "s.streams.exr", tmp_path / "pt2n.exr"
    small.write(streams)
    cvtrace.write_image(pt2n_file, pt2n)
    out = tmp_path / f"{method}.exr"
    done = run_cli(cli, "reconstruct", streams, "--method", method, "--pt2n", pt2n_file, "-o", out)
    assert done.returncode == 0, done.stderr
    assert same_bits(cvtrace.reconstruct(small, method, pt2n=pt2n), cvtrace.read_image(out))


def test_a_missing_pt2n_image_raises_the_cli_message(small, cli, tmp_path):
    streams = tmp_path / "s.streams.exr"
    small.write(streams)
    with pytest.raises(cvtrace.Error) as e:
        cvtrace.reconstruct(small, "pt2n-oidn")
    assert str(e.value) == cli_error(cli, "reconstruct", streams, "--method", "pt2n-oidn", "-o", tmp_path / "o.exr")
    with pytest.raises(cvtrace.Error, match="2x2"):
        cvtrace.reconstruct(small, "pt2n-oidn", pt2n=np.ones((2, 2, 3)))


def test_bad_options_raise_the_cli_messages(small, cli, tmp_path):
    streams = tmp_path / "s.streams.exr"
    small.write(streams)
    out = tmp_path / "o.exr"
    cases = [
        (dict(method="bilateral"), ["--method", "bilateral"]),
        (dict(method="ours", kk=3), ["--param", "ours.kk=3"]),
        (dict(method="ours", k=0), ["--param", "ours.k=0"]),
        (dict(method="ours", select="nearest"), ["--param", "ours.select=nearest"]),
        (dict(method="iduw", window=4), ["--method", "iduw", "--param", "iduw.window=4"]),
    ]
    for kwargs, flags in cases:
        with pytest.raises(cvtrace.Error) as e:
            cvtrace.reconstruct(small, **kwargs)
        assert str(e.value).replace("Streams", "") == cli_error(cli, "reconstruct", streams, "-o", out, *flags).replace(str(streams), ""), kwargs
    with pytest.raises(cvtrace.Error, match="one estimator"):
        cvtrace.reconstruct(small, "all")
    with pytest.raises(TypeError, match="cvtrace.Streams or the path"):
        cvtrace.reconstruct(42)
    # Needs: iduw takes a multiple of 4 batches.
    three = cvtrace.Streams.from_arrays(np.ones((3, 4, 4, 3)), np.ones((3, 4, 4, 3)), spp=3)
    with pytest.raises(cvtrace.Error, match="iduw"):
        cvtrace.reconstruct(three, "iduw")


def test_specs_and_help():
    ours = next(e for e in cvtrace.estimators() if e["name"] == "ours")
    assert ours["label"] and ours["samples"] == "2n" and ours["colour"].startswith("#") and not ours["python"]
    k = next(p for p in ours["params"] if p["name"] == "k")
    assert k["kind"] == "int" and k["default"] == "49" and k["range"] == "integer 1..64" and k["flag"] == "--k" and k["doc"]
    select = next(p for p in ours["params"] if p["name"] == "select")
    assert select["choices"] == ["knn", "window", "random", "gbuffer"]
    assert any(v["key"].startswith("ours-") for v in ours["variants"])
    text = cvtrace.estimator_help("ours")
    assert text.startswith("ours — ") and "ours.k = 49" in text
    with pytest.raises(cvtrace.Error, match="unknown estimator"):
        cvtrace.estimator_help("nope")
    assert "ours" in cvtrace.reconstruct.__doc__ and "threads" in cvtrace.reconstruct.__text_signature__


def test_the_gil_is_released_while_reconstructing():
    big = cvtrace.Streams.from_arrays(
        np.random.default_rng(0).random((8, 192, 192, 3), dtype=np.float32),
        np.random.default_rng(1).random((8, 192, 192, 3), dtype=np.float32),
        spp=8,
    )
    assert_releases_the_gil(lambda: cvtrace.reconstruct(big, "ours", threads=1))
