#!/usr/bin/env bash
# cvtrace against Mitsuba 3 on the same scenes, machine and run (scripts/compare_mitsuba.py).
#
# Installs what it needs, idempotently: python3-venv and libllvm19 through scripts/setup.sh
# (Mitsuba's llvm_ad_rgb JIT needs LLVM >= 16; Debian 12's default 14/15 fail), Mitsuba 3 from
# PyPI (with numpy) into .cache/mitsuba-venv, and a release build of cvtrace. Arguments go to the script,
# e.g. --threads 2 --spp 128.
set -euo pipefail
cd "$(dirname "$0")/.."
MITSUBA_VERSION=${MITSUBA_VERSION:-3.9.1}
bash scripts/setup.sh python3-venv libllvm19
venv=.cache/mitsuba-venv
if [[ ! -x $venv/bin/python ]] || ! $venv/bin/python -c "import mitsuba, numpy, sys; sys.exit(mitsuba.__version__ != '$MITSUBA_VERSION')" 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q "mitsuba==$MITSUBA_VERSION" numpy
fi
cargo build --release --locked -q
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-$(ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* /usr/lib/*/libLLVM-19.so 2>/dev/null | head -n1)}
exec "$venv/bin/python" scripts/compare_mitsuba.py "$@"
