"""Another renderer's samples: Mitsuba 3's PT and CRN streams of its Cornell box, reconstructed
by cvtrace, beat Mitsuba's own path tracer at the same total samples (fixed seeds)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import cvtrace

pytest.importorskip("mitsuba")
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "mitsuba_crn.py"


def example():
    spec = importlib.util.spec_from_file_location("mitsuba_crn", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_crn_stream_shares_its_random_numbers_across_pixels():
    m = example()
    mi, scene = m.load_scene(16)
    streams = m.render_streams(mi, scene, spp=4, batches=2, seed=5)
    assert streams.pt_batches.shape == (2, 16, 16, 3) and streams.albedo.shape == (16, 16, 3)
    # Neighbouring pixels' CRN batch deviations move together; the PT ones do not.
    def neighbour_correlation(batches):
        d = (batches - batches.mean(axis=0)).sum(axis=3)
        return float(np.corrcoef(d[:, :, :-1].ravel(), d[:, :, 1:].ravel())[0, 1])
    assert neighbour_correlation(streams.crn_batches) > 0.5 > neighbour_correlation(streams.pt_batches)


def test_ours_on_mitsuba_streams_beats_mitsuba_pt_at_equal_samples():
    scores = example().compare(size=64, spp=32, batches=8, seed=1, reference_spp=1024)
    pt = scores["mitsuba pt (64 spp)"]
    assert scores["ours"] < 0.8 * pt, scores
    assert scores["ours"] < scores["average"] and scores["ours"] < scores["pt"], scores
