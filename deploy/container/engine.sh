#!/usr/bin/env bash
# Sourced by build.sh and run.sh: the podman command line that works on machines like the one
# the project is built on (see docs/container.md), and a check that says which known failure
# a machine meets instead of hiding it.
#
# - runtime runc: podman's default runtime crun stops at "cgroups in hybrid mode not supported"
#   on hosts with cgroups v1 plus a v2 mount; runc runs there and everywhere else;
# - explicit --ulimit: podman otherwise asks for higher RLIMIT_NOFILE/NPROC than a process
#   without CAP_SYS_RESOURCE may set ("setrlimit ... Operation not permitted"); limits at or
#   below the caller's own hard limits are always allowed.

IMAGE="${IMAGE:-localhost/twincell:latest}"

container_die() {
    echo "container: $*" >&2
    exit 1
}

# Installs the Debian packages "$@" unless their commands are there already.
container_install() {
    command -v apt-get >/dev/null 2>&1 \
        || container_die "needs apt-get to install $* (Debian or Ubuntu), or install them yourself"
    [ "$(id -u)" = 0 ] || container_die "installing $* needs root"
    echo "container: installing $*" >&2
    apt-get update -qq || container_die "apt-get update failed"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null \
        || container_die "apt-get install $* failed"
}

[ "$(id -u)" = 0 ] \
    || container_die "run as root: these scripts use rootful podman (rootless podman needs subuid/subgid ranges for the caller and fuse-overlayfs; see docs/container.md)"
if ! command -v podman >/dev/null 2>&1 || ! command -v runc >/dev/null 2>&1; then
    container_install podman runc uidmap fuse-overlayfs
fi

# The lower of 4096 and the caller's hard limit, for NOFILE and NPROC.
cap_limit() {
    local hard="$1"
    if [ "$hard" = unlimited ] || [ "$hard" -gt 4096 ]; then echo 4096; else echo "$hard"; fi
}
nofile=$(cap_limit "$(ulimit -Hn)")
nproc=$(cap_limit "$(ulimit -Hu)")
PODMAN=(podman --runtime runc)
ULIMITS=(--ulimit "nofile=$nofile:$nofile" --ulimit "nproc=$nproc:$nproc")
