"""Ctrl-C: KeyboardInterrupt, at once, and nothing half-written left behind."""

from __future__ import annotations

import _thread
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import cvtrace
from conftest import CORNELL

# Renders of a minute or more on two cores: always still running when interrupted.
LONG = dict(spp=1024, batches=16, width=256, height=256)


def test_keyboard_interrupt_in_process_stops_the_render(tmp_path):
    out = tmp_path / "long.streams.exr"
    timer = threading.Timer(1.0, _thread.interrupt_main)
    timer.start()
    start = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        cvtrace.render(CORNELL, output=out, **LONG)
    timer.join()
    assert time.perf_counter() - start < 20
    assert list(tmp_path.iterdir()) == []


SCRIPT = """
import sys, cvtrace
print("start", flush=True)
try:
    cvtrace.render(sys.argv[1], output=sys.argv[2], spp=256, batches=16, width=256, height=256)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
    sys.exit(3)
print("finished", flush=True)
"""


def test_sigint_while_writing_leaves_no_temporary_file(tmp_path):
    out = tmp_path / "long.streams.exr"
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(CORNELL), str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "start"
        # Wait until the file is being written (its temporary is there), then press Ctrl-C.
        deadline = time.monotonic() + 300
        while not any(p.name.startswith(".long.streams.exr.tmp-") for p in tmp_path.iterdir()):
            assert proc.poll() is None, "the render ended before it was interrupted"
            assert time.monotonic() < deadline, "no temporary file appeared"
            time.sleep(0.02)
        proc.send_signal(signal.SIGINT)
        output, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3 and "KeyboardInterrupt" in output, output
    assert sorted(p.name for p in Path(tmp_path).iterdir()) == []
