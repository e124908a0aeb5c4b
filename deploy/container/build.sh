#!/usr/bin/env bash
# Builds the image localhost/twincell:latest from Debian's packages, with no registry pull:
#
# 1. the base image localhost/debian-base:CODENAME, the host's Debian release made with
#    mmdebstrap from Debian's mirrors and imported into podman (once; about 30 s);
# 2. the release binary, built on the host with the project's own build (scripts/setup.sh,
#    cargo build --release --locked), or TWINCELL_BIN if set;
# 3. `podman build` of the Containerfile on that base, in a context holding the binary,
#    assets/ and scenarios/: Mesa's EGL/GL drivers from Debian, then the files.
#
# Needs root (rootful podman). Installs podman, runc, uidmap, fuse-overlayfs and mmdebstrap if
# missing. Environment: IMAGE (default localhost/twincell:latest), BASE (a base image to use
# instead of making one), TWINCELL_BIN (a binary built already) with TWINCELL_HOME (the checkout
# it was built in, where it looks for its detector; default this one), REBUILD_BASE=1 (remake
# the base). Every failure stops it with the step and the engine's own message.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
source deploy/container/engine.sh
started=$SECONDS

# The base has the host's release, so the host-built binary finds the glibc it was linked to.
# shellcheck disable=SC1091
codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
if [ -z "${BASE:-}" ]; then
    [ -n "$codename" ] || container_die "cannot read VERSION_CODENAME from /etc/os-release; set BASE to a Debian image of this machine's release"
    BASE="localhost/debian-base:$codename"
    if [ "${REBUILD_BASE:-0}" = 1 ] || ! "${PODMAN[@]}" image exists "$BASE"; then
        command -v mmdebstrap >/dev/null 2>&1 || container_install mmdebstrap
        base_tar=$(mktemp /tmp/twincell-base.XXXXXX.tar)
        trap 'rm -f "$base_tar"' EXIT
        echo "container: making $BASE with mmdebstrap (Debian $codename, with its updates and security mirrors)" >&2
        t0=$SECONDS
        # --variant=apt: essential packages plus apt, so the Containerfile can apt-get install.
        mmdebstrap --quiet --variant=apt "$codename" "$base_tar" \
            "deb http://deb.debian.org/debian $codename main" \
            "deb http://deb.debian.org/debian $codename-updates main" \
            "deb http://deb.debian.org/debian-security $codename-security main" \
            || container_die "mmdebstrap $codename failed (above); it needs Debian's mirrors reachable"
        "${PODMAN[@]}" import --quiet "$base_tar" "$BASE" >/dev/null \
            || container_die "podman import of the base failed (above)"
        rm -f "$base_tar"
        echo "container: base made in $((SECONDS - t0)) s" >&2
    fi
fi

if [ -n "${TWINCELL_BIN:-}" ]; then
    bin="$TWINCELL_BIN"
else
    source scripts/setup.sh
    nice -n 10 cargo build --release --locked --bin twincell
    bin="$CARGO_TARGET_DIR/release/twincell"
fi
[ -x "$bin" ] || container_die "no binary at $bin"
# The binary finds the shipped detector under the checkout it was compiled in (its
# CARGO_MANIFEST_DIR), so the image keeps the assets at that path.
home="${TWINCELL_HOME:-$repo}"
[ "${home#/}" != "$home" ] || container_die "TWINCELL_HOME must be an absolute path, got $home"
grep -aqF "$home" "$bin" \
    || container_die "$bin was not built in $home (the path is nowhere in it); set TWINCELL_HOME to the checkout that built it"

context=$(mktemp -d /tmp/twincell-image.XXXXXX)
trap 'rm -rf "$context" "${base_tar:-}"' EXIT
# Without its debug information (the release profile keeps line tables: 400 MB of the binary);
# the symbols stay, so a panic's backtrace still names its functions.
if command -v strip >/dev/null 2>&1; then
    strip --strip-debug -o "$context/twincell" "$bin" || container_die "strip $bin failed"
else
    echo "container: no strip (binutils) here; the image gets the binary with its debug information" >&2
    cp "$bin" "$context/twincell"
fi
cp -r assets scenarios "$context/"
cp Containerfile "$context/Containerfile"

echo "container: building $IMAGE on $BASE" >&2
previous=$("${PODMAN[@]}" image inspect --format '{{.Id}}' "$IMAGE" 2>/dev/null || true)
t0=$SECONDS
# --network host: the apt-get step reaches Debian's mirrors through the host's network.
"${PODMAN[@]}" build --quiet --network host "${ULIMITS[@]}" \
    --build-arg "BASE=$BASE" --build-arg "TWINCELL_HOME=$home" \
    -t "$IMAGE" -f "$context/Containerfile" "$context" >/dev/null \
    || container_die "podman build failed (above)"
build_s=$((SECONDS - t0))
# The image this build replaced is left without a name; remove it unless a container uses it.
current=$("${PODMAN[@]}" image inspect --format '{{.Id}}' "$IMAGE")
if [ -n "$previous" ] && [ "$previous" != "$current" ]; then
    "${PODMAN[@]}" rmi "$previous" >/dev/null 2>&1 || true
fi

# The image must start and find its libraries; this is the first place a machine that cannot
# run containers at all says so, with the runtime's own message.
version=$("${PODMAN[@]}" run --rm --network none "${ULIMITS[@]}" "$IMAGE" --version 2>&1) \
    || container_die "the image was built but cannot run here: $version"
version=$(head -n 1 <<<"$version")
size=$("${PODMAN[@]}" image inspect --format '{{.Size}}' "$current")
echo "container: $IMAGE ($version) built in ${build_s} s, $((size / 1000000)) MB; $((SECONDS - started)) s in all" >&2
