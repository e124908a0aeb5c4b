#!/usr/bin/env bash
# Runs `twincell ARGS...` in the image localhost/twincell:latest (deploy/container/build.sh),
# with the current directory mounted at the same path and as the working directory, so
# relative scenario and --out paths mean the same inside and out. It runs as the caller's user
# and group, so the files it writes are the caller's, and without a network (twincell needs
# none). Exit status: twincell's.
set -euo pipefail
source "$(dirname "$0")/engine.sh"
"${PODMAN[@]}" image exists "$IMAGE" \
    || container_die "no image $IMAGE; build it with deploy/container/build.sh"
tty=()
[ -t 0 ] && [ -t 1 ] && tty=(-it)
exec "${PODMAN[@]}" run --rm "${tty[@]}" --network none "${ULIMITS[@]}" \
    --user "$(id -u):$(id -g)" --security-opt label=disable \
    -v "$PWD:$PWD" -w "$PWD" "$IMAGE" "$@"
