"""Finishes the wheel `maturin build --auditwheel repair` made, for `make python`.

The repair copies the libraries the extension module links (Embree, TBB, Open Image Denoise and
its core) into `cvtrace.libs/` under hashed names. Two things it cannot know are done here:

- Open Image Denoise loads its CPU device as a module at run time, from the folder of its core
  library, by its plain name (`libOpenImageDenoise_device_cpu.so.<version>`), so no link names
  it. It is copied next to the bundled core, its links pointed at the bundled core and TBB and
  its rpath at its own folder.
- The extension module keeps the rpath of the build (the absolute folder of `.deps/oidn/lib`,
  which the repair needed to find the libraries); the wheel must find only its own copies.

    python finish_wheel.py WHEEL --oidn-lib DIR --patchelf PATCHELF -o OUT_DIR
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

LIBS = "cvtrace.libs"


def record_line(root: Path, path: Path) -> str:
    data = path.read_bytes()
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{path.relative_to(root).as_posix()},sha256={digest},{len(data)}"


def bundled(libs: Path, pattern: str) -> str:
    """The name the repair gave the library whose name matches `pattern`."""
    found = [p.name for p in libs.iterdir() if re.fullmatch(pattern, p.name)]
    if len(found) != 1:
        sys.exit(f"finish_wheel: expected one {pattern} in {LIBS}/, found {found or 'none'}")
    return found[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("wheel", type=Path)
    ap.add_argument("--oidn-lib", type=Path, required=True, help="the folder of Open Image Denoise's libraries (.deps/oidn/lib)")
    ap.add_argument("--patchelf", default="patchelf")
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args()

    def patchelf(*a: str) -> None:
        subprocess.run([args.patchelf, *a], check=True)

    with tempfile.TemporaryDirectory(prefix="cvtrace-wheel-") as tmp:
        root = Path(tmp)
        with zipfile.ZipFile(args.wheel) as z:
            names = z.namelist()
            z.extractall(root)
            modes = {i.filename: i.external_attr for i in z.infolist()}
        libs = root / LIBS
        core = bundled(libs, r"libOpenImageDenoise_core-[0-9a-f]+\.so\.[0-9.]+")
        tbb = bundled(libs, r"libtbb-[0-9a-f]+\.so\.12")
        version = core.split(".so.", 1)[1]
        device_name = f"libOpenImageDenoise_device_cpu.so.{version}"
        source = args.oidn_lib / device_name
        if not source.is_file():
            sys.exit(f"finish_wheel: {source}: no such file (the CPU device of Open Image Denoise {version}); run scripts/setup.sh")
        device = libs / device_name
        shutil.copyfile(source, device)
        device.chmod(0o755)
        patchelf(
            "--replace-needed", f"libOpenImageDenoise_core.so.{version}", core,
            "--replace-needed", "libtbb.so.12", tbb,
            "--force-rpath", "--set-rpath", "$ORIGIN",
            str(device),
        )
        extension = next((root / "cvtrace").glob("_cvtrace*.so"))
        # DT_RPATH, not RUNPATH: the bundled Embree has no rpath of its own and finds the bundled
        # TBB through the rpath of the module that loads it, which only DT_RPATH is.
        patchelf("--force-rpath", "--set-rpath", f"$ORIGIN/../{LIBS}", str(extension))

        dist_info = next(root.glob("*.dist-info"))
        record = dist_info / "RECORD"
        files = sorted(p for p in root.rglob("*") if p.is_file() and p != record)
        record.write_text("".join(record_line(root, p) + "\n" for p in files) + f"{record.relative_to(root).as_posix()},,\n")

        args.output.mkdir(parents=True, exist_ok=True)
        out = args.output / args.wheel.name
        partial = out.with_name(out.name + ".partial")
        order = [n for n in names if not n.endswith("RECORD") and (root / n).is_file()]
        order += [p.relative_to(root).as_posix() for p in files if p.relative_to(root).as_posix() not in order]
        order.append(record.relative_to(root).as_posix())
        with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=6) as z:
            for name in order:
                info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = modes.get(name, (0o755 if name.endswith((".so",)) or ".so." in name else 0o644) << 16)
                z.writestr(info, (root / name).read_bytes())
        partial.replace(out)
        print(out)


if __name__ == "__main__":
    main()
