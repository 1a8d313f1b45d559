#!/usr/bin/env bash
# A single-node Slurm cluster for the tests, as background processes of this user: config and
# state under a temporary directory, a private munge socket and key, no accounting.
#   eval "$(.ci/slurm-cluster.sh start)"   # prints the exports (SLURM_CONF, RAYSCOPE_SLURM, ...)
#   .ci/slurm-cluster.sh stop DIR           # stops the daemons by PID, removes DIR
# Prints a NOTICE (and exports nothing) where the daemons are missing or do not come up.
set -uo pipefail

notice() { echo "NOTICE: $*" >&2; }

start() {
    for b in slurmctld slurmd munged sbatch scontrol; do
        if ! command -v "$b" >/dev/null 2>&1 && [ ! -x "/usr/sbin/$b" ]; then
            notice "no $b here: the Slurm tests will skip"
            return 0
        fi
    done
    export PATH="$PATH:/usr/sbin"
    local dir
    dir="$(mktemp -d /tmp/rayscope-slurm.XXXXXX)"
    mkdir -p "$dir"/{state,spool,munge,log}
    chmod 700 "$dir/munge"
    dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
    chmod 400 "$dir/munge/munge.key"
    munged --key-file="$dir/munge/munge.key" --socket="$dir/munge/socket" \
        --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/seed" \
        --force 2>>"$dir/log/munged.log" || { notice "munged did not start (see $dir/log)"; return 0; }
    local user cpus mem host
    user="$(id -un)"
    cpus="$(nproc)"
    mem="$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)"
    host="$(hostname -s)"
    cat >"$dir/slurm.conf" <<CONF
ClusterName=rayscope-ci
SlurmctldHost=$host(127.0.0.1)
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
AuthInfo=socket=$dir/munge/socket
CredType=cred/munge
SlurmctldPort=$((20000 + RANDOM % 20000))
SlurmdPort=$((40000 + RANDOM % 10000))
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MinJobAge=86400
MaxArraySize=100001
SlurmctldTimeout=10
SlurmdTimeout=10
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=main Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF="$dir/slurm.conf"
    slurmctld -f "$SLURM_CONF" 2>>"$dir/log/slurmctld.err" || { notice "slurmctld did not start (see $dir/log)"; stop_dir "$dir"; return 0; }
    slurmd -f "$SLURM_CONF" -N "$host" 2>>"$dir/log/slurmd.err" || { notice "slurmd did not start (see $dir/log)"; stop_dir "$dir"; return 0; }
    for _ in $(seq 1 100); do
        if sinfo -h -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
            echo "export SLURM_CONF=$dir/slurm.conf RAYSCOPE_SLURM=$dir PATH=\"\$PATH:/usr/sbin\""
            return 0
        fi
        sleep 0.1
    done
    notice "the Slurm node did not come up (see $dir/log)"
    stop_dir "$dir"
}

stop_dir() {
    local dir="$1"
    [ -d "$dir" ] || return 0
    for pidfile in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
        [ -f "$pidfile" ] && kill "$(cat "$pidfile")" 2>/dev/null
    done
    sleep 0.3
    case "$dir" in /tmp/rayscope-slurm.*) rm -rf "$dir" ;; esac
}

case "${1:-}" in
    start) start ;;
    stop) stop_dir "${2:-${RAYSCOPE_SLURM:-}}" ;;
    *) echo "usage: $0 start | stop DIR" >&2; exit 2 ;;
esac
