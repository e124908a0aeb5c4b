#!/usr/bin/env bash
# Sourced by scripts/slurm-up.sh (one node) and scripts/slurm-cluster-up.sh (nodes in network
# namespaces): root, Debian's slurm-wlm and munge installed, munged running with the one key every
# host of a cluster shares. Each failure exits 1 with what failed; nothing is skipped.

# The caller sets SLURM_SCRIPT (its name) before sourcing.
die() {
    echo "${SLURM_SCRIPT:-slurm}: $*" >&2
    exit 1
}

[ "$(id -u)" = 0 ] || die "must run as root (it installs packages and starts munged, slurmctld and slurmd)"
command -v apt-get >/dev/null 2>&1 || die "needs apt-get (Debian or Ubuntu) to install slurm-wlm and munge"

if ! command -v slurmctld >/dev/null 2>&1 || ! command -v slurmd >/dev/null 2>&1 \
    || ! command -v munged >/dev/null 2>&1 || ! command -v sbatch >/dev/null 2>&1; then
    echo "${SLURM_SCRIPT:-slurm}: installing slurm-wlm and munge" >&2
    apt-get update -qq || die "apt-get update failed"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        slurm-wlm munge >/dev/null || die "apt-get install slurm-wlm munge failed"
fi

# Starts munged unless one already answers. Its socket is a file (/run/munge), so daemons in
# other network namespaces of this machine reach the same munged.
munge_up() {
    if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
        return 0
    fi
    if [ -s /run/munge/munged.pid ]; then
        kill "$(cat /run/munge/munged.pid)" 2>/dev/null || true
        sleep 1
    fi
    install -d -o munge -g munge -m 0700 /etc/munge /var/lib/munge /var/log/munge
    install -d -o munge -g munge -m 0755 /run/munge
    if [ ! -s /etc/munge/munge.key ]; then
        dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
    fi
    chown munge:munge /etc/munge/munge.key
    chmod 0400 /etc/munge/munge.key
    runuser -u munge -- /usr/sbin/munged \
        || die "munged did not start: $(tail -n 20 /var/log/munge/munged.log 2>/dev/null)"
    munge -n | unmunge >/dev/null || die "munge cannot encode and decode a credential"
}
