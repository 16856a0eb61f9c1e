#!/usr/bin/env bash
# A real Slurm cluster on this machine, for the farm tests and for trying `cvtrace farm`:
# munged with its own key and socket, one slurmctld and two slurmd (nodes node1, node2, one CPU
# each) on free ports, every file under one scratch folder. Needs root and Debian's slurm-wlm and
# munge (scripts/setup.sh installs them); no systemd.
#
#   scripts/slurm_local.sh up   [DIR]   # start (or find running) the cluster; prints `export SLURM_CONF=...`
#   scripts/slurm_local.sh down [DIR]   # stop what `up` started there
#
# DIR defaults to $CVTRACE_SLURM_DIR, else /tmp/cvtrace-slurm. Both commands are idempotent. `down`
# ends only the processes `up` started: the PIDs in DIR's pid files, and only if that process
# still runs this cluster's configuration.
set -euo pipefail

cmd=${1:-}
dir=${2:-${CVTRACE_SLURM_DIR:-/tmp/cvtrace-slurm}}
case "$cmd" in
    up | down) ;;
    *)
        echo "usage: $0 up|down [DIR]" >&2
        exit 2
        ;;
esac
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
conf=$dir/slurm.conf
host=$(hostname -s)

# PID files of the daemons, each with the text its command line must contain to be ours.
pidfiles=("$dir/munge/munged.pid" "$dir/slurmctld.pid" "$dir/slurmd-node1.pid" "$dir/slurmd-node2.pid")

# The PID in $1 if that process is alive and runs with this cluster's files.
ours() {
    local pid
    pid=$(cat "$1" 2>/dev/null) || return 1
    [[ "$pid" =~ ^[0-9]+$ ]] || return 1
    tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | grep -qF -- "$dir/" || return 1
    echo "$pid"
}

down() {
    local f pid i
    # The slurmds first, then the controller, then munged (they authenticate through it).
    for f in "${pidfiles[@]:1}" "${pidfiles[0]}"; do
        if pid=$(ours "$f"); then
            kill "$pid" 2>/dev/null || true
            for ((i = 0; i < 100; i++)); do
                kill -0 "$pid" 2>/dev/null || break
                sleep 0.1
            done
            if kill -0 "$pid" 2>/dev/null; then
                kill -9 "$pid" 2>/dev/null || true
            fi
        fi
        rm -f "$f"
    done
}

if [[ "$cmd" == down ]]; then
    down
    echo "slurm_local: stopped the cluster in $dir" >&2
    exit 0
fi

running=0
for f in "${pidfiles[@]}"; do
    ours "$f" >/dev/null && running=$((running + 1))
done
if ((running == ${#pidfiles[@]})) && SLURM_CONF=$conf sinfo -h >/dev/null 2>&1; then
    echo "slurm_local: already up in $dir" >&2
    echo "export SLURM_CONF=$conf"
    exit 0
fi
# Half up (a daemon died): start over.
down

for tool in munged slurmctld slurmd sinfo; do
    command -v "$tool" >/dev/null || {
        echo "slurm_local: $tool not found; run scripts/setup.sh (Debian packages slurm-wlm, munge)" >&2
        exit 1
    }
done

# A free TCP port at or after $1 (nothing listening on 127.0.0.1 there, none handed out yet).
taken=()
free_port() {
    local p=$1
    while (echo >"/dev/tcp/127.0.0.1/$p") 2>/dev/null || [[ " ${taken[*]} " == *" $p "* ]]; do
        p=$((p + 1))
    done
    taken+=("$p")
    echo "$p"
}
base=$((20000 + RANDOM % 20000))
ctld_port=$(free_port "$base")
taken+=("$ctld_port")
node1_port=$(free_port $((ctld_port + 1)))
taken+=("$node1_port")
node2_port=$(free_port $((node1_port + 1)))

# munged: its own key (folder 0700) and socket (folder 0755).
rm -rf "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
mkdir -p "$dir/munge/key" "$dir/munge/run" "$dir/state" "$dir/spool/node1" "$dir/spool/node2" "$dir/log"
chmod 0755 "$dir/munge" "$dir/munge/run"
chmod 0700 "$dir/munge/key"
head -c 1024 /dev/urandom >"$dir/munge/key/munge.key"
chmod 0400 "$dir/munge/key/munge.key"
socket=$dir/munge/run/munge.socket
munged --force --socket="$socket" --key-file="$dir/munge/key/munge.key" --pid-file="$dir/munge/munged.pid" \
    --log-file="$dir/munge/munged.log" --seed-file="$dir/munge/munged.seed"

cat >"$conf" <<EOF
# Written by scripts/slurm_local.sh: a one-machine cluster for tests.
ClusterName=cvtrace-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool/%n
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd-%n.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd-%n.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
DependencyParameters=kill_invalid_depend
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
MailProg=/bin/true
ReturnToService=2
MinJobAge=600
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=node1 NodeHostname=$host NodeAddr=127.0.0.1 Port=$node1_port CPUs=1 State=UNKNOWN
NodeName=node2 NodeHostname=$host NodeAddr=127.0.0.1 Port=$node2_port CPUs=1 State=UNKNOWN
PartitionName=local Nodes=node1,node2 Default=YES MaxTime=INFINITE State=UP
EOF

export SLURM_CONF=$conf
slurmctld -c -f "$conf"
slurmd -f "$conf" -N node1
slurmd -f "$conf" -N node2

# Up when both nodes are idle (about a second).
for ((i = 0; i < 300; i++)); do
    idle=$(sinfo -h -N -t idle -o %N 2>/dev/null | sort -u | wc -l)
    ((idle == 2)) && break
    sleep 0.1
done
if ((idle != 2)); then
    echo "slurm_local: the nodes did not come up; logs in $dir/log" >&2
    sinfo -N >&2 || true
    down
    exit 1
fi
echo "slurm_local: up in $dir (slurmctld on port $ctld_port, node1 $node1_port, node2 $node2_port)" >&2
echo "export SLURM_CONF=$conf"
