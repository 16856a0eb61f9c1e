#!/usr/bin/env bash
# Runs the README's test command (.ci/run) inside a Debian 13 (trixie) root, where Debian's
# Embree is 4.x, so the Embree 4 side of crates/embree-sys (bindgen on its headers) is built and tested too
# (Debian 12, the CI machine, only has Embree 3). Needs root, network access to
# deb.debian.org and a Rust toolchain in ~/.cargo and ~/.rustup, which is bind-mounted.
#
# The root is made once with debootstrap in .cache/debian13-root (about 40 s; 3 GB once the
# build dependencies are in) and reused; the tests run on a fresh clone of HEAD inside it
# (removed afterwards), so uncommitted changes are not tested.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD

(( EUID == 0 )) || { echo "test_debian13: needs root (debootstrap, chroot, bind mounts)" >&2; exit 1; }
bash scripts/setup.sh debootstrap
for d in "$HOME/.cargo" "$HOME/.rustup"; do
    [[ -d $d ]] || { echo "test_debian13: $d not found: the chroot borrows the host's Rust toolchain" >&2; exit 1; }
done

root=$repo/.cache/debian13-root
if [[ ! -x $root/usr/bin/make ]]; then
    echo "test_debian13: creating a Debian 13 root in $root" >&2
    rm -rf "$root.tmp"
    debootstrap --variant=minbase --include=make,git,ca-certificates trixie "$root.tmp" http://deb.debian.org/debian \
        >"$repo/.cache/debian13-debootstrap.log" 2>&1 \
        || { tail -20 "$repo/.cache/debian13-debootstrap.log" >&2; echo "test_debian13: debootstrap failed" >&2; exit 1; }
    mv "$root.tmp" "$root"
fi
cp /etc/resolv.conf "$root/etc/resolv.conf"

mounted=()
cleanup() {
    local i
    for (( i = ${#mounted[@]} - 1; i >= 0; i-- )); do umount -R "${mounted[i]}" || true; done
    rm -rf "$root/root/cvtrace"   # the clone and its build, about 5 GB
}
trap cleanup EXIT
bind() { mkdir -p "$root$2"; mount --bind "$1" "$root$2"; mounted+=("$root$2"); }
bind "$HOME/.cargo" /root/.cargo
bind "$HOME/.rustup" /root/.rustup
mkdir -p "$root/proc"; mount -t proc proc "$root/proc"; mounted+=("$root/proc")
# Debian 13's slurmd (24.11) initialises its cgroup plugin whatever the config says, and fails
# without /sys/fs/cgroup.
mkdir -p "$root/sys"; mount --rbind /sys "$root/sys"; mount --make-rslave "$root/sys"; mounted+=("$root/sys")

rm -rf "$root/root/cvtrace"
git clone -q "$repo" "$root/root/cvtrace"
echo "test_debian13: running .ci/run on $(git rev-parse --short HEAD) in Debian $(cat "$root/etc/debian_version")" >&2
chroot "$root" /usr/bin/env -i HOME=/root PATH=/root/.cargo/bin:/usr/sbin:/usr/bin:/sbin:/bin TERM=dumb \
    bash -c 'cd /root/cvtrace && bash .ci/run'

# The build script records which Embree it found; make sure it was Embree 4.
origin=$(cat "$root"/root/cvtrace/target/debug/build/cvtrace-*/output | sed -n 's/^cargo:rustc-env=CVTRACE_EMBREE_ORIGIN=//p' | head -n 1)
echo "test_debian13: built against ${origin:-an unknown Embree}" >&2
grep -q embree4 <<<"$origin" || { echo "test_debian13: expected Embree 4 in Debian 13" >&2; exit 1; }
echo "test_debian13: passed" >&2
