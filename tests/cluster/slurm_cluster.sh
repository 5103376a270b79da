#!/usr/bin/env bash
# shellcheck disable=SC2317  # stop_cluster and what it calls run from the EXIT trap
# Runs a command against a single-node Slurm cluster of its own: munged, slurmctld and slurmd on this machine
# (127.0.0.1, two free ports), every file of theirs in WORK/slurm (slurm.conf and gres.conf written there, fresh
# state), started before the command and always stopped after it: on success, on failure and on a signal. The
# daemons run in the foreground as this script's children with a parent-death signal, so they end with it even
# when it is killed; job steps left over (slurmstepd and its tasks) are found by the SLURM_CONF they carry.
#
# Usage: tests/cluster/slurm_cluster.sh WORK COMMAND [ARGS...]
#   COMMAND runs in WORK with SLURM_CONF set (sbatch, squeue, ... talk to this cluster).
# Exit status: COMMAND's; 77 when Slurm cannot start on this machine (the reason is printed). Needs root (the
# daemons run as root) and Debian's slurm-wlm and munge (.ci/deps installs them).
set -uo pipefail

if [ $# -lt 2 ]; then
  echo "usage: $0 WORK COMMAND [ARGS...]" >&2
  exit 2
fi
WORK="$(cd "$1" && pwd)" || { echo "slurm_cluster.sh: no such folder $1" >&2; exit 2; }
shift
DIR="$WORK/slurm"
CANNOT_START=77

cannot_start() {
  echo "slurm_cluster.sh: cannot start Slurm here: $*" >&2
  exit "$CANNOT_START"
}

for tool in munged slurmctld slurmd slurmstepd sbatch squeue scancel sinfo setpriv; do
  command -v "$tool" >/dev/null 2>&1 ||
    cannot_start "$tool is not installed (Debian: apt-get install slurm-wlm munge; bash .ci/deps installs them)"
done
[ "$(id -u)" -eq 0 ] || cannot_start "the daemons run as root (SlurmUser=root) and this is uid $(id -u)"

# Two TCP ports nothing listens on (a cluster of another test or a real Slurm may hold the default 6817/6818).
listening_ports() {
  # /proc/net/tcp{,6}: local address "HEXIP:HEXPORT", state 0A = LISTEN
  local local_address state
  cat /proc/net/tcp /proc/net/tcp6 2>/dev/null | awk '$4 == "0A" {print $2, $4}' |
    while read -r local_address state; do echo "$((16#${local_address##*:}))"; done
}
free_port() {
  local taken port
  taken=" $(listening_ports | tr '\n' ' ') $* "
  for _ in $(seq 200); do
    port=$((20000 + RANDOM % 40000))
    case "$taken" in *" $port "*) continue ;; esac
    echo "$port"
    return 0
  done
  return 1
}
CTLD_PORT="$(free_port)" || cannot_start "no free TCP port found"
SLURMD_PORT="$(free_port "$CTLD_PORT")" || cannot_start "no free TCP port found"

rm -rf "$DIR"
mkdir -p "$DIR/state" "$DIR/spool" || cannot_start "cannot create $DIR"
HOST="$(uname -n)"
HOST="${HOST%%.*}"  # slurmctld compares SlurmctldHost with the short host name
# munge: a fresh random key, readable by its owner only (munged refuses a key others can read).
if ! head -c 1024 /dev/urandom > "$DIR/munge.key" || ! chmod 400 "$DIR/munge.key"; then
  cannot_start "cannot write the munge key $DIR/munge.key"
fi

# The node offers two GPUs, so two array tasks run at once, each with the `--gpus=1` it asks for. Slurm counts
# a GPU only with a device file; /dev/null and /dev/zero stand in for them (no task plugin confines a task to
# its devices, and dvs finds the device through Vulkan, not through these files).
cat > "$DIR/slurm.conf" <<EOF
ClusterName=dvstest
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
AuthType=auth/munge
AuthInfo=socket=$DIR/munge.socket
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/slurmctld.log
SlurmdLogFile=$DIR/slurmd.log
MailProg=/bin/true
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
GresTypes=gpu
ReturnToService=2
SlurmdParameters=config_overrides
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$(nproc) Gres=gpu:2 State=UNKNOWN
PartitionName=debug Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
cat > "$DIR/gres.conf" <<EOF
AutoDetect=off
NodeName=$HOST Name=gpu File=/dev/null
NodeName=$HOST Name=gpu File=/dev/zero
EOF
# SLURM_CONF is given to the daemons and the command only, never exported here: it marks their processes.
CONF="$DIR/slurm.conf"
with_conf() { SLURM_CONF="$CONF" "$@"; }

DAEMON_PIDS=()
COMMAND_PID=""
# Leftover job steps: slurmstepd and the tasks it started outlive slurmd (they daemonize); every one of them
# carries this cluster's SLURM_CONF in its environment, and nothing else on the machine does.
cluster_processes() {
  local env_file pid
  for env_file in /proc/[0-9]*/environ; do
    pid="${env_file#/proc/}"; pid="${pid%/environ}"
    { tr '\0' '\n' < "$env_file"; } 2>/dev/null | grep -qxF "SLURM_CONF=$CONF" && echo "$pid"
  done
}
stop_cluster() {
  trap - EXIT INT TERM HUP
  local ids=() left=() pid
  if [ -n "$COMMAND_PID" ] && kill -0 "$COMMAND_PID" 2>/dev/null; then
    kill -TERM "$COMMAND_PID" 2>/dev/null
    wait "$COMMAND_PID" 2>/dev/null
  fi
  mapfile -t ids < <(with_conf squeue -h -o %A 2>/dev/null)
  if [ ${#ids[@]} -gt 0 ]; then
    echo "slurm_cluster.sh: cancelling jobs still in the queue: ${ids[*]}" >&2
    with_conf scancel "${ids[@]}" 2>/dev/null
    for _ in $(seq 20); do [ -z "$(with_conf squeue -h -o %A 2>/dev/null)" ] && break; sleep 0.5; done
  fi
  for pid in "${DAEMON_PIDS[@]}"; do kill -TERM "$pid" 2>/dev/null; done
  for pid in "${DAEMON_PIDS[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
  done
  mapfile -t left < <(cluster_processes | grep -vxF -f <(printf '%s\n' "${DAEMON_PIDS[@]}"))
  if [ ${#left[@]} -gt 0 ]; then
    echo "slurm_cluster.sh: ending job processes left behind: ${left[*]}" >&2
    kill -KILL "${left[@]}" 2>/dev/null
  fi
}
trap stop_cluster EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
trap 'exit 129' HUP

start_daemon() {  # NAME COMMAND...: in the background, ended by SIGTERM when this script ends
  SLURM_CONF="$CONF" setpriv --pdeathsig TERM "${@:2}" > "$DIR/$1.out" 2>&1 &
  DAEMON_PIDS+=($!)
}
show_logs() {
  local f
  for f in "$DIR"/munged.out "$DIR"/slurmctld.out "$DIR"/slurmctld.log "$DIR"/slurmd.out "$DIR"/slurmd.log; do
    [ -s "$f" ] && { echo "--- $f (last lines)"; tail -n 15 "$f"; }
  done >&2
}
daemon_gone() {  # the daemon started last is no longer running
  ! kill -0 "${DAEMON_PIDS[-1]}" 2>/dev/null
}

start_daemon munged munged --foreground --force --socket="$DIR/munge.socket" --key-file="$DIR/munge.key" \
  --pid-file="$DIR/munged.pid" --log-file="$DIR/munged.log" --seed-file="$DIR/munged.seed"
for _ in $(seq 100); do [ -S "$DIR/munge.socket" ] || daemon_gone && break; sleep 0.1; done
[ -S "$DIR/munge.socket" ] || { show_logs; cannot_start "munged did not open its socket $DIR/munge.socket"; }

start_daemon slurmctld slurmctld -D -c -i
start_daemon slurmd slurmd -D
state=""
for _ in $(seq 120); do
  state="$(with_conf sinfo -h -n "$HOST" -o %t 2>/dev/null)"
  [ "$state" = "idle" ] && break
  sleep 0.25
done
if [ "$state" != "idle" ]; then
  show_logs
  cannot_start "the node did not come up in 30 s (sinfo says '${state:-nothing}'; the daemons' logs are above)"
fi
echo "slurm_cluster.sh: Slurm $(with_conf sinfo -V | awk '{print $2}') up on $HOST: ports $CTLD_PORT/$SLURMD_PORT, $(nproc) CPUs, 2 GPUs, files in $DIR" >&2

# In the background and waited for, so that a signal to this script stops the cluster at once (bash runs a trap
# only after a foreground command ends); stop_cluster ends the command too.
(cd "$WORK" && export SLURM_CONF="$CONF" && exec "$@") &
COMMAND_PID=$!
wait "$COMMAND_PID"
exit $?
