#!/usr/bin/env bash
# Brings up a multi-node Slurm cluster on this machine: slurmctld and NODES slurmd daemons
# (default 3), each host in its own network namespace (`ip netns`) with its own address and host
# name, joined by veth pairs to a bridge in the root namespace, where the clients (sbatch,
# squeue, scontrol) run. The hosts share this machine's file system, as cluster nodes share a
# network file system, and one munged. For scripts/slurm-node-loss-test.sh and for trying
# deploy/slurm-array.sh on several nodes by hand:
#
#   bash scripts/slurm-cluster-up.sh          # prints the SLURM_CONF line the clients need
#   export SLURM_CONF=/etc/twincell-cluster/slurm.conf; sinfo -N
#   bash scripts/slurm-cluster-up.sh --down   # stops every daemon and removes the namespaces
#
# It stays clear of scripts/slurm-up.sh's one-node cluster: its own slurm.conf, state, logs and
# pid files, and its daemons listen only inside their namespaces. Re-running is safe: it tears
# down what an earlier run left first.
#
# Environment: NODES (default 3), NODE_CPUS (CPUs each node offers, default 1), NODE_MEM_MB
# (default 2000), CLUSTER_NET (the /24's first three octets, default 10.228.28),
# SLURMD_TIMEOUT (seconds without an answer before slurmctld marks a node down, default 5).
#
# Needs root, iproute2 and a kernel that lets it make network and UTS namespaces, veth pairs and
# a bridge. Where it cannot, it says which step failed, with the kernel's message, and exits 1:
# it never falls back to one node.
set -euo pipefail
SLURM_SCRIPT=slurm-cluster-up
NODES="${NODES:-3}"
NODE_CPUS="${NODE_CPUS:-1}"
NODE_MEM_MB="${NODE_MEM_MB:-2000}"
CLUSTER_NET="${CLUSTER_NET:-10.228.28}"
SLURMD_TIMEOUT="${SLURMD_TIMEOUT:-5}"
conf_dir=/etc/twincell-cluster
state_dir=/var/lib/twincell-cluster
log_dir=/var/log/twincell-cluster
run_dir=/run/twincell-cluster
bridge=tcbr28

hosts() {
    echo tc-ctl
    for i in $(seq "$NODES"); do echo "tc-n$i"; done
}

# Kills every process in the cluster's namespaces, then removes them and the bridge.
down() {
    local ns pids
    for ns in $(ip netns list 2>/dev/null | awk '/^tc-(ctl|n[0-9]+)( |$)/ {print $1}'); do
        pids=$(ip netns pids "$ns" 2>/dev/null || true)
        [ -z "$pids" ] || kill -9 $pids 2>/dev/null || true
        ip netns del "$ns" 2>/dev/null || true
    done
    ip link del "$bridge" 2>/dev/null || true
    rm -rf "$run_dir"
}

if [ "${1:-}" = --down ]; then
    [ "$(id -u)" = 0 ] || { echo "$SLURM_SCRIPT: must run as root" >&2; exit 1; }
    down
    echo "$SLURM_SCRIPT: cluster stopped, namespaces removed" >&2
    exit 0
fi

source "$(dirname "$0")/slurm-common.sh"
if ! command -v ip >/dev/null 2>&1; then
    echo "$SLURM_SCRIPT: installing iproute2 (ip makes the network namespaces)" >&2
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
        --no-install-recommends iproute2 >/dev/null; } || die "apt-get install iproute2 failed"
fi
command -v unshare >/dev/null 2>&1 || die "needs unshare (util-linux) to give each node its host name"
[ "$NODES" -ge 1 ] && [ "$NODES" -le 50 ] || die "NODES must be 1 to 50, got $NODES"

down
munge_up

# A step that needs what some machines do not allow (a container without CAP_NET_ADMIN or
# CAP_SYS_ADMIN, a kernel without veth or bridge support): name the step and the kernel's reply.
must() {
    local what="$1"
    shift
    local out
    out=$("$@" 2>&1) || die "cannot $what on this machine: \`$*\` said: ${out:-nothing} -- multi-node needs root with CAP_NET_ADMIN and CAP_SYS_ADMIN and a kernel with network namespaces, veth and bridge"
}

must "make a bridge" ip link add "$bridge" type bridge
must "address the bridge" ip addr add "$CLUSTER_NET.254/24" dev "$bridge"
must "bring the bridge up" ip link set "$bridge" up
n=0
for host in $(hosts); do
    n=$((n + 1))
    addr="$CLUSTER_NET.$n"
    must "make network namespace $host" ip netns add "$host"
    must "make a veth pair for $host" ip link add "v-$host" type veth peer name eth0 netns "$host"
    must "attach $host to the bridge" ip link set "v-$host" master "$bridge" up
    must "address $host" ip -n "$host" addr add "$addr/24" dev eth0
    must "bring up $host's links" ip -n "$host" link set eth0 up
    must "bring up $host's loopback" ip -n "$host" link set lo up
    # Other addresses of this machine (srun on a submit host) through the bridge's address.
    must "route $host" ip -n "$host" route add default via "$CLUSTER_NET.254"
done
install -d "$conf_dir" "$state_dir" "$log_dir" "$run_dir"
rm -f "$log_dir"/*.log
rm -rf "${state_dir:?}"/*
for host in $(hosts); do install -d "$state_dir/$host"; done
{
    cat <<CONF
# Written by twincell's scripts/slurm-cluster-up.sh: slurmctld and $NODES slurmd nodes, each in
# its own network namespace on one machine. %n is a node's name.
ClusterName=twincell-ns
SlurmctldHost=tc-ctl($CLUSTER_NET.1)
SlurmUser=root
AuthType=auth/munge
# How long a job's credential lives; a job requeued after its node died waits this long before
# it may start again (the default 120 s would dominate the test).
AuthInfo=cred_expire=5
StateSaveLocation=$state_dir/tc-ctl
SlurmdSpoolDir=$state_dir/%n
SlurmctldPidFile=$run_dir/slurmctld.pid
SlurmdPidFile=$run_dir/slurmd-%n.pid
SlurmctldLogFile=$log_dir/slurmctld.log
SlurmdLogFile=$log_dir/slurmd-%n.log
# A node that does not answer for this long is marked DOWN and its jobs requeued. slurmctld
# pings every third of it, and a ping round lasts until each node answers or the message
# times out: a short MessageTimeout (all hosts are on one bridge) keeps the rounds short.
SlurmdTimeout=$SLURMD_TIMEOUT
MessageTimeout=3
# No cgroups in a container: track processes by their parents, bind nothing.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
# Look at the queue every 2 s (default 60 s, backfill 30 s), so a requeued task that waits on
# nothing else starts once its credential has expired.
SchedulerParameters=sched_interval=2,bf_interval=2
MpiDefault=none
# A killed node stays DOWN until an administrator returns it: the test loses it for good.
ReturnToService=0
JobRequeue=1
# Keep finished jobs visible to scontrol for 10 minutes (there is no accounting database).
MinJobAge=600
CONF
    n=1
    for host in $(hosts | tail -n +2); do
        n=$((n + 1))
        echo "NodeName=$host NodeAddr=$CLUSTER_NET.$n CPUs=$NODE_CPUS RealMemory=$NODE_MEM_MB State=UNKNOWN"
    done
    echo "PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP"
} >"$conf_dir/slurm.conf"
export SLURM_CONF="$conf_dir/slurm.conf"

# Each daemon in its host's network namespace and a UTS namespace of its own, whose host name
# is how slurmd finds its NodeName; daemons fork into the background and keep both. nsenter,
# not `ip netns exec`: the latter mounts a fresh /sys without /sys/fs/cgroup, and slurmd stops
# when it finds no cgroup file system.
start_in() {
    local host="$1"
    shift
    nsenter --net="/run/netns/$host" unshare --uts sh -c 'hostname "$0" && exec "$@"' "$host" "$@"
}
start_in tc-ctl slurmctld -i \
    || die "slurmctld did not start: $(tail -n 20 "$log_dir/slurmctld.log" 2>/dev/null)"
for host in $(hosts | tail -n +2); do
    start_in "$host" slurmd \
        || die "slurmd on $host did not start: $(tail -n 20 "$log_dir/slurmd-$host.log" 2>/dev/null)"
done

# Wait (up to a minute) for every node to register and become idle.
for _ in $(seq 60); do
    idle=$(sinfo -h -N -o '%N %T' 2>/dev/null | awk '$2 == "idle"' | wc -l)
    [ "$idle" -lt "$NODES" ] || break
    sleep 1
done
if [ "$idle" -lt "$NODES" ]; then
    sinfo -N >&2 || true
    echo "--- slurmctld.log" >&2
    tail -n 30 "$log_dir/slurmctld.log" >&2 || true
    for host in $(hosts | tail -n +2); do
        echo "--- slurmd-$host.log" >&2
        tail -n 10 "$log_dir/slurmd-$host.log" >&2 || true
    done
    die "$idle of $NODES nodes idle after 60 s"
fi
echo "$SLURM_SCRIPT: $NODES nodes idle ($NODE_CPUS CPUs, $NODE_MEM_MB MB each), slurmctld at $CLUSTER_NET.1; clients need:" >&2
echo "export SLURM_CONF=$SLURM_CONF"
