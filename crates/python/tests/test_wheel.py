"""The installed package uses the native libraries its wheel carries, not those of the build
machine (Debian's Embree, setup's Open Image Denoise in .deps), so it works where pip put it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cvtrace

# In a process of its own, so that what other tests imported (Mitsuba) is not in its maps.
SCRIPT = """
import json, numpy as np, cvtrace
rng = np.random.default_rng(0)
features = dict(albedo=rng.random((16, 16, 3)), normal=np.tile([0.0, 0.0, 1.0], (16, 16, 1)), depth=rng.random((16, 16)))
s = cvtrace.Streams.from_arrays(rng.random((4, 16, 16, 3)), rng.random((4, 16, 16, 3)), spp=4, **features)
cvtrace.reconstruct(s, "oidn")  # the denoiser loads its CPU device only when it first runs
maps = [l.split(maxsplit=5)[-1] for l in open("/proc/self/maps").read().splitlines()]
print(json.dumps(sorted({p for p in maps if p.startswith("/") and ".so" in p})))
"""


def test_the_native_libraries_come_from_the_wheel():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    loaded = [Path(p) for p in json.loads(done.stdout)]
    libs = Path(cvtrace.__file__).resolve().parent.parent / "cvtrace.libs"
    for stem in ["libembree3", "libtbb", "libOpenImageDenoise-", "libOpenImageDenoise_core", "libOpenImageDenoise_device_cpu"]:
        paths = [p for p in loaded if p.name.startswith(stem)]
        assert paths, f"{stem} is not loaded: {[p.name for p in loaded]}"
        assert all(p.parent == libs for p in paths), f"{stem} loaded from {paths}, not from {libs}"
