"""cvtrace.Streams: the file round trip, streams from arrays and their checks."""

from __future__ import annotations

import numpy as np
import pytest

import cvtrace
from conftest import same_bits

FIELDS = ("pt", "crn", "pt_batches", "crn_batches", "albedo", "normal", "depth")


def test_read_of_write_is_bit_exact(small, tmp_path):
    path = tmp_path / "s.streams.exr"
    small.write(path)
    back = cvtrace.Streams.read(path)
    for name in FIELDS:
        assert same_bits(getattr(back, name), getattr(small, name)), name
    assert back.provenance == small.provenance and back.settings == small.settings
    assert (back.spp, back.seed, back.max_depth, back.scene, back.version) == (small.spp, small.seed, small.max_depth, small.scene, small.version)
    with pytest.raises(cvtrace.Error, match="exists"):
        small.write(path)
    small.write(path, overwrite=True)
    with pytest.raises(cvtrace.Error, match=r"\.exr"):
        small.write(tmp_path / "s.png")
    with pytest.raises(cvtrace.Error, match="does not exist"):
        small.write(tmp_path / "missing" / "s.exr")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.streams.exr"]


def test_from_arrays_round_trips_and_takes_array_likes(tmp_path):
    rng = np.random.default_rng(1)
    pt = rng.random((4, 5, 6, 3), dtype=np.float32)
    crn = rng.random((4, 5, 6, 3)).astype(np.float64)  # another dtype: converted
    s = cvtrace.Streams.from_arrays(pt, crn.tolist(), spp=8, seed=7, scene="other renderer")
    assert (s.height, s.width, s.batches, s.spp, s.seed) == (5, 6, 4, 8, 7)
    assert s.albedo is None and s.provenance is None
    assert np.allclose(s.pt, pt.mean(axis=0), atol=1e-6) and same_bits(s.pt_batches, pt)
    path = tmp_path / "arrays.streams.exr"
    s.write(path)
    back = cvtrace.Streams.read(path)
    for name in ("pt", "crn", "pt_batches", "crn_batches"):
        assert same_bits(getattr(back, name), getattr(s, name)), name
    assert back.scene == "other renderer" and back.seed == 7
    # Fortran order, and features.
    f = cvtrace.Streams.from_arrays(
        np.asfortranarray(pt), crn, albedo=np.ones((5, 6, 3)), normal=np.zeros((5, 6, 3)), depth=np.ones((5, 6)), spp=8
    )
    assert f.albedo.shape == (5, 6, 3) and f.depth.shape == (5, 6) and same_bits(f.pt_batches, pt)


def test_from_arrays_checks_as_a_stream_file_is():
    ok = np.ones((2, 3, 4, 3), np.float32)
    with pytest.raises(ValueError, match=r"pt_batches: expected an array of shape \(B, H, W, 3\), got \(3, 4, 3\)"):
        cvtrace.Streams.from_arrays(ok[0], ok)
    with pytest.raises(ValueError, match="crn_batches"):
        cvtrace.Streams.from_arrays(ok, ok[..., :2])
    with pytest.raises(cvtrace.Error, match="pt has 2 batches and crn has 1"):
        cvtrace.Streams.from_arrays(ok, ok[:1])
    with pytest.raises(cvtrace.Error, match=r"crn.b00.RGB.*is 4x2"):
        cvtrace.Streams.from_arrays(ok, ok[:, :2])
    bad = ok.copy()
    bad[1, 2, 3, 1] = np.nan
    with pytest.raises(cvtrace.Error, match=r"pt.b01.G.*\(3, 2\)|pt.G.*\(3, 2\)"):
        cvtrace.Streams.from_arrays(bad, ok)
    with pytest.raises(cvtrace.Error, match="not the stream's samples"):
        cvtrace.Streams.from_arrays(ok, ok, pt=np.zeros((3, 4, 3)))
    with pytest.raises(cvtrace.Error, match="do not split into 2 equal batches"):
        cvtrace.Streams.from_arrays(ok, ok, spp=3)
    with pytest.raises(ValueError, match="come together"):
        cvtrace.Streams.from_arrays(ok, ok, albedo=np.ones((3, 4, 3)))
    with pytest.raises(TypeError, match="pt_batches: not an array of numbers"):
        cvtrace.Streams.from_arrays("abc", ok)
    with pytest.raises(ValueError, match="no batches"):
        cvtrace.Streams.from_arrays(ok[:0], ok[:0])


def test_bad_files_are_named(tmp_path):
    junk = tmp_path / "junk.exr"
    junk.write_bytes(b"not an exr")
    with pytest.raises(cvtrace.Error, match="junk.exr"):
        cvtrace.Streams.read(junk)
    with pytest.raises(cvtrace.Error, match="no-such.exr"):
        cvtrace.Streams.read(tmp_path / "no-such.exr")
    rgb = tmp_path / "rgb.exr"
    cvtrace.write_image(rgb, np.ones((2, 2, 3)))
    with pytest.raises(cvtrace.Error, match="is an RGB image"):
        cvtrace.Streams.read(rgb)
