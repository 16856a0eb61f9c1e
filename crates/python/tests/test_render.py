"""cvtrace.render and render_reference: shapes, types, determinism, provenance, the CLI's file."""

from __future__ import annotations


import numpy as np
import pytest

import cvtrace
from conftest import CORNELL, SMALL, assert_releases_the_gil, cli_error, run_cli, same_bits


def test_streams_are_float32_hwc_read_only_views(small):
    s = small
    assert (s.width, s.height, s.batches, s.spp, s.seed) == (32, 32, 4, 16, 3)
    for a in (s.pt, s.crn, s.albedo, s.normal):
        assert a.shape == (32, 32, 3) and a.dtype == np.float32 and a.flags.c_contiguous
        assert not a.flags.writeable
    assert s.depth.shape == (32, 32) and s.depth.dtype == np.float32
    for b in (s.pt_batches, s.crn_batches):
        assert b.shape == (4, 32, 32, 3) and b.dtype == np.float32 and b.flags.c_contiguous
    # The stream mean is the mean of its batches; np.asarray copies nothing.
    assert np.allclose(s.pt_batches.mean(axis=0), s.pt, rtol=1e-5, atol=1e-6)
    assert np.shares_memory(np.asarray(s.pt), s.pt)
    with pytest.raises(ValueError):
        s.pt[0, 0, 0] = 1.0
    assert s.pt.mean() > 0.01 and np.isfinite(s.pt).all()
    assert "32x32" in repr(s) and "16 spp" in repr(s)


def test_provenance_records_the_render(small):
    p = small.provenance
    assert p["size"] == "32x32" and p["seed"] == "3" and p["spp"] == "16" and p["batches"] == "4"
    assert p["traversal"] == "fast" and p["scene hash"] and p["camera"]
    assert small.scene.endswith("scene.gltf") and small.version


def test_same_seed_same_bits_for_any_thread_count(small):
    one = cvtrace.render(CORNELL, threads=1, **SMALL)
    assert same_bits(one.pt_batches, small.pt_batches) and same_bits(one.crn, small.crn)
    other = cvtrace.render(CORNELL, **{**SMALL, "seed": 4})
    assert not same_bits(other.pt, small.pt)


def test_defines_and_size(small):
    direct = cvtrace.render(CORNELL, spp=4, batches=2, width=16, max_depth=2)
    assert (direct.height, direct.width, direct.max_depth) == (16, 16, 2)
    # Direct light only is darker than the full transport.
    assert direct.pt.mean() < small.pt.mean()
    grey = cvtrace.render(CORNELL, spp=4, batches=1, width=8, height=4, **{"environment.color": (0.5, 0.5, 0.5)})
    assert grey.pt.shape == (4, 8, 3)


def test_render_matches_the_cli_file_bit_for_bit(small, cli, tmp_path):
    out = tmp_path / "cli.streams.exr"
    done = run_cli(cli, "render", CORNELL, "--spp", 16, "--batches", 4, "--seed", 3, "--width", 32, "--height", 32, "-o", out)
    assert done.returncode == 0, done.stderr
    from_cli = cvtrace.Streams.read(out)
    for name in ("pt", "crn", "pt_batches", "crn_batches", "albedo", "normal", "depth"):
        assert same_bits(getattr(from_cli, name), getattr(small, name)), name
    assert from_cli.provenance == small.provenance


def test_output_keeps_the_file_and_refuses_to_replace_it(tmp_path):
    out = tmp_path / "kept.streams.exr"
    s = cvtrace.render(CORNELL, spp=2, batches=1, width=8, height=8, output=out)
    assert out.is_file() and s.origin == str(out)
    with pytest.raises(cvtrace.Error, match="exists"):
        cvtrace.render(CORNELL, spp=2, batches=1, width=8, height=8, output=out)
    cvtrace.render(CORNELL, spp=2, batches=1, width=8, height=8, output=out, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.streams.exr"]


def test_render_reference_is_a_pt_image():
    img = cvtrace.render_reference(CORNELL, spp=8, width=16, height=16, seed=9)
    assert img.shape == (16, 16, 3) and img.dtype == np.float32 and img.flags.writeable
    again = cvtrace.render_reference(CORNELL, spp=8, width=16, height=16, seed=9, threads=1)
    assert same_bits(img, again)


def test_bad_input_raises_the_cli_message(cli, tmp_path):
    missing = tmp_path / "nope.gltf"
    with pytest.raises(cvtrace.Error) as e:
        cvtrace.render(missing, spp=4)
    assert str(e.value) == cli_error(cli, "render", missing, "--spp", 4, "-o", tmp_path / "x.exr")
    with pytest.raises(cvtrace.Error) as e:
        cvtrace.render(CORNELL, spp=6, batches=4)
    assert "4" in str(e.value) and "6" in str(e.value)
    with pytest.raises(cvtrace.Error) as e:
        cvtrace.render(CORNELL, spp=4, colour=3)
    assert str(e.value) == cli_error(cli, "render", CORNELL, "--spp", 4, "-D", "colour=3", "-o", tmp_path / "x.exr")
    with pytest.raises(ValueError, match="traversal"):
        cvtrace.render(CORNELL, spp=4, traversal="sloppy")
    with pytest.raises(ValueError, match="threads"):
        cvtrace.render(CORNELL, spp=4, threads=0)
    with pytest.raises(OverflowError):
        cvtrace.render(CORNELL, spp=-1)
    with pytest.raises(cvtrace.Error, match="spp"):
        cvtrace.render(CORNELL, spp=0)
    with pytest.raises(ValueError, match="camera"):
        cvtrace.render(CORNELL, spp=4, camera=(1, 2))
    with pytest.raises(cvtrace.Error, match=r"\.exr"):
        cvtrace.render(CORNELL, spp=4, output=tmp_path / "x.png")
    assert list(tmp_path.iterdir()) == []


def test_the_gil_is_released_while_rendering():
    assert_releases_the_gil(lambda: cvtrace.render(CORNELL, spp=64, batches=4, width=64, height=64, threads=1))
