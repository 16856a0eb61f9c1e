#!/bin/sh
# Downloads and unpacks the third-party sources of validation/tools/validation_scenes.py into DEST
# (default /tmp/cvtrace-validation-sources). Idempotent: what is already there is not fetched
# again. Needs pip, unzip, tar, apt-get and dpkg-deb (Debian 12's package lists).
#
#   validation/tools/fetch_validation_sources.sh [DEST]
#
# Resulting layout (what validation_scenes.py expects):
#   DEST/sionna_rt-2.2.0/sionna/rt/scenes/{munich,etoile,san_francisco}/...     (PyPI sionna-rt 2.2.0)
#   DEST/genesis_world-1.4.5/genesis/assets/meshes/dragon.obj     (PyPI genesis-world 1.4.5)
#   DEST/libcgal-demo-5.5.1-2/data/meshes/*.off                   (Debian libcgal-demo 5.5.1-2)
#   DEST/libcgal-dev-5.5.1-2/copyright                            (that package's licence file)
set -eu
DEST=${1:-/tmp/cvtrace-validation-sources}
mkdir -p "$DEST"
cd "$DEST"

wheel() { # pypi-name version dir members...
    name=$1 ver=$2 dir=$3
    shift 3
    whl=$(echo "$name" | tr - _)-$ver-py3-none-any.whl
    [ -f "$whl" ] || pip download --no-deps --no-cache-dir -q -d . "$name==$ver"
    if [ ! -d "$dir" ]; then
        mkdir -p "$dir.tmp"
        unzip -q -o "$whl" "$@" -d "$dir.tmp"
        mv "$dir.tmp" "$dir"
    fi
}
wheel sionna-rt 2.2.0 sionna_rt-2.2.0 'sionna/rt/scenes/munich/*' 'sionna/rt/scenes/etoile/*' \
    'sionna/rt/scenes/san_francisco/*' \
    'sionna_rt-2.2.0.dist-info/licenses/*'
wheel genesis-world 1.4.5 genesis_world-1.4.5 'genesis/assets/meshes/dragon.obj' \
    'genesis_world-1.4.5.dist-info/licenses/*'

if [ ! -d libcgal-demo-5.5.1-2 ]; then
    [ -f libcgal-demo_5.5.1-2_all.deb ] || apt-get download libcgal-demo=5.5.1-2
    mkdir -p cgal.tmp libcgal-demo-5.5.1-2
    dpkg-deb --fsys-tarfile libcgal-demo_5.5.1-2_all.deb | tar x -C cgal.tmp ./usr/share/doc/libcgal-dev/data.tar.gz
    tar xzf cgal.tmp/usr/share/doc/libcgal-dev/data.tar.gz -C libcgal-demo-5.5.1-2 data/meshes
    rm -r cgal.tmp
fi
# libcgal-demo's doc folder is a link to libcgal-dev's, which holds the copyright file.
if [ ! -f libcgal-dev-5.5.1-2/copyright ]; then
    [ -f libcgal-dev_5.5.1-2_amd64.deb ] || apt-get download libcgal-dev=5.5.1-2
    mkdir -p cgaldev.tmp libcgal-dev-5.5.1-2
    dpkg-deb --fsys-tarfile libcgal-dev_5.5.1-2_amd64.deb | tar x -C cgaldev.tmp ./usr/share/doc/libcgal-dev/copyright
    mv cgaldev.tmp/usr/share/doc/libcgal-dev/copyright libcgal-dev-5.5.1-2/copyright
    rm -r cgaldev.tmp
fi

sha256sum sionna_rt-2.2.0-py3-none-any.whl genesis_world-1.4.5-py3-none-any.whl \
    libcgal-demo_5.5.1-2_all.deb libcgal-dev_5.5.1-2_amd64.deb
