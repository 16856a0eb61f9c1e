#!/usr/bin/env bash
# Installs cvtrace's system dependencies (Debian/Ubuntu) and checks for cargo.
#
# Idempotent and quiet: each package is checked with dpkg-query, and apt runs
# (update + install) only when something is missing. Pass -v for details; further arguments
# are extra packages to ensure (scripts/compare_mitsuba.sh adds its own).
#   libembree-dev       Embree headers + library (ray casting; build.rs needs it)
#   clang libclang-dev  bindgen's parser for the Embree headers
#   pkg-config          Embree discovery where a .pc file exists
#   embree-tools        ships the Cornell box source model (scenes/cornell-box/SOURCE.md)
#   openimageio-tools   oiiotool/idiff, used by tests to cross-check EXR output
#   assimp-utils        model conversion for new scenes
#   chromium            headless browser for the viewer test
#   slurm-wlm munge     a real Slurm cluster on this machine (scripts/slurm_local.sh) for the farm tests
set -euo pipefail

verbose=0
[[ "${1:-}" == "-v" ]] && { verbose=1; shift; }
say() { if (( verbose )); then echo "setup: $*"; fi; }

packages=(libembree-dev embree-tools openimageio-tools clang libclang-dev pkg-config assimp-utils chromium slurm-wlm munge "$@")

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
say "all dependencies present"
