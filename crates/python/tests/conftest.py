"""Shared fixtures: the bundled Cornell box rendered small, the `cvtrace` binary, and a check
that a call releases the GIL."""

from __future__ import annotations

import os
import shutil
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import cvtrace

ROOT = Path(__file__).resolve().parents[3]
CORNELL = ROOT / "scenes" / "cornell-box" / "scene.gltf"
CORNELL_REF = ROOT / "scenes" / "cornell-box" / "scene.ref.exr"

# A small, quick render: 32x32, 16 spp per stream in 4 batches (iduw needs a multiple of 4).
SMALL = dict(spp=16, batches=4, seed=3, width=32, height=32)


@pytest.fixture(scope="session")
def small() -> cvtrace.Streams:
    return cvtrace.render(CORNELL, **SMALL)


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `cvtrace` binary of this checkout (`cargo test` builds target/debug/cvtrace; CI
    sets CVTRACE_REQUIRE_TOOLS, so a missing one fails instead of skipping)."""
    for candidate in [os.environ.get("CVTRACE_BIN"), ROOT / "target" / "debug" / "cvtrace", ROOT / "target" / "release" / "cvtrace", shutil.which("cvtrace")]:
        if candidate and Path(candidate).is_file():
            return Path(candidate)
    if os.environ.get("CVTRACE_REQUIRE_TOOLS"):
        pytest.fail("no cvtrace binary (build it with cargo build, or set CVTRACE_BIN)")
    pytest.skip("no cvtrace binary")


def run_cli(binary: Path, *args: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(binary), "--log", "error", *map(str, args)], capture_output=True, text=True, check=False)


def cli_error(binary: Path, *args: object) -> str:
    """The message `cvtrace` prints for a failing command, without its `error: ` prefix."""
    done = run_cli(binary, *args)
    assert done.returncode != 0, done
    lines = [l for l in done.stderr.splitlines() if l.startswith("error: ")]
    assert lines, done.stderr
    return lines[-1][len("error: ") :]


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def assert_releases_the_gil(call) -> None:
    """Runs `call` while another Python thread ticks every 2 ms: the call must take a while and
    the ticks go on all along, with no gap anywhere near the call's length."""
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.002)

    t = threading.Thread(target=tick)
    t.start()
    start = time.perf_counter()
    try:
        call()
    finally:
        end = time.perf_counter()
        stop.set()
        t.join()
    during = [x for x in ticks if start < x < end]
    assert end - start > 0.05 and len(during) > 5
    assert max(np.diff([start, *during, end])) < max(0.05, (end - start) / 3)
