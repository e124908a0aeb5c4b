#!/usr/bin/env bash
# Brings up a one-node Slurm cluster on this machine (slurmctld and slurmd on localhost, munge
# for authentication), for the Slurm test (scripts/slurm-test.sh) and for trying
# deploy/slurm-array.sh by hand. Needs root and Debian's packages (bookworm: Slurm 22.05).
#
# The node is what this machine has: its CPU count and memory, no cgroups
# (proctrack/linuxproc, task/none), no accounting daemon. Re-running is safe: it restarts
# the daemons with a fresh configuration.
#
# Fails loudly, never skips: if a package cannot be installed or a daemon does not come up,
# it prints the daemon's log and exits 1.
set -euo pipefail

SLURM_SCRIPT=slurm-up
source "$(dirname "$0")/slurm-common.sh"

# Stop the daemons a previous run left, by the pids they recorded.
for pidfile in /run/slurmctld.pid /run/slurmd.pid; do
    if [ -s "$pidfile" ]; then
        kill "$(cat "$pidfile")" 2>/dev/null || true
    fi
done
sleep 1
munge_up

host=$(hostname -s)
cpus=$(nproc)
# Leave the system 512 MB; Slurm refuses jobs that ask more memory than RealMemory.
mem_mb=$(( $(awk '/^MemTotal:/ {print $2}' /proc/meminfo) / 1024 - 512 ))
conf_dir=/etc/slurm
install -d "$conf_dir" /var/lib/slurm/slurmctld /var/lib/slurm/slurmd /var/log/slurm
cat >"$conf_dir/slurm.conf" <<CONF
# Written by twincell's scripts/slurm-up.sh: a one-node cluster on $host.
ClusterName=twincell
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
StateSaveLocation=/var/lib/slurm/slurmctld
SlurmdSpoolDir=/var/lib/slurm/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
# No cgroups in a container: track processes by their parents, bind nothing.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
# CPUs are the consumable: a node of $cpus CPUs runs $cpus one-CPU tasks at once.
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
# Keep finished jobs visible to scontrol for 10 minutes (there is no accounting database).
MinJobAge=600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF

slurmctld -i || die "slurmctld did not start: $(tail -n 20 /var/log/slurm/slurmctld.log 2>/dev/null)"
slurmd || die "slurmd did not start: $(tail -n 20 /var/log/slurm/slurmd.log 2>/dev/null)"

# Wait (up to a minute) for the node to register and become usable.
for _ in $(seq 60); do
    state=$(sinfo -h -N -o '%T' 2>/dev/null | head -n 1 || true)
    case "$state" in
        idle | mixed | allocated) break ;;
    esac
    sleep 1
done
case "${state:-}" in
    idle | mixed | allocated) ;;
    *)
        echo "--- slurmctld.log" >&2
        tail -n 30 /var/log/slurm/slurmctld.log >&2 || true
        echo "--- slurmd.log" >&2
        tail -n 30 /var/log/slurm/slurmd.log >&2 || true
        die "node $host is '${state:-unknown}', not idle, after 60 s"
        ;;
esac
out=$(timeout 60 srun -N1 -n1 hostname) || die "srun hostname failed"
echo "slurm-up: node $host ($cpus CPUs, $mem_mb MB) is $state; srun ran on $out" >&2
