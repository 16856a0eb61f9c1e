#!/bin/sh
# Downloads and unpacks the third-party models of scenes/tools/import_scenes.py into DEST
# (default /tmp/cvtrace-scene-sources). Idempotent: what is already there is not fetched again.
# Needs curl, tar, and for the engine apt-get + dpkg (Debian 12) and for the teapot npm.
#
#   scenes/tools/fetch_scene_sources.sh [DEST]
#
# Resulting layout (what import_scenes.py expects):
#   DEST/obj-rs-0.7.4/tests/fixtures/sponza.obj                 (crates.io obj-rs 0.7.4)
#   DEST/easy-gltf-1.1.5/tests/head.glb                         (crates.io easy-gltf 1.1.5)
#   DEST/package/teapot.js                                      (npm teapot 1.0.0)
#   DEST/assimp/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb
#                                                               (Debian assimp-testmodels 5.2.5~ds0-1)
set -eu
DEST=${1:-/tmp/cvtrace-scene-sources}
mkdir -p "$DEST"
cd "$DEST"

crate() { # name version
    if [ ! -d "$1-$2" ]; then
        [ -f "$1-$2.crate" ] || curl -sSfL -o "$1-$2.crate" "https://static.crates.io/crates/$1/$1-$2.crate"
        tar xzf "$1-$2.crate"
    fi
}
crate obj-rs 0.7.4
crate easy-gltf 1.1.5

if [ ! -f package/teapot.js ]; then
    [ -f teapot-1.0.0.tgz ] || npm pack teapot@1.0.0 >/dev/null
    tar xzf teapot-1.0.0.tgz
fi

if [ ! -d assimp/usr/share/assimp ]; then
    ls assimp-testmodels_*_all.deb >/dev/null 2>&1 || apt-get download assimp-testmodels
    dpkg -x assimp-testmodels_*_all.deb assimp
fi

sha256sum obj-rs-0.7.4.crate easy-gltf-1.1.5.crate teapot-1.0.0.tgz assimp-testmodels_*_all.deb
