#!/usr/bin/env bash
# A single-node SLURM cluster on this machine, for testing the workflow's SLURM path (tests/test_cluster.py):
# munged, slurmctld and slurmd on localhost, as root, with a minimal configuration in a state directory of its own.
#
#   .ci/slurm-single-node.sh start    # writes $STATE/slurm.conf, starts the daemons, waits for the node to be idle
#   .ci/slurm-single-node.sh status
#   .ci/slurm-single-node.sh stop     # stops the daemons that `start` started, by their pid files, and nothing else
#
# Needs Debian's slurm-wlm and munge packages (apt-get install -y slurm-wlm munge). The configuration is the least
# that runs jobs without cgroups or a database: proctrack/linuxproc, task/none, select/cons_tres on CPUs, no
# accounting (no slurmdbd). Without accounting `sacct` answers nothing, so the Snakemake executor must be told to
# read job states with `squeue` (--slurm-status-command squeue); MinJobAge keeps finished jobs visible to squeue
# for 10 min. The one partition is called `cpu`, as in workflow/profiles/slurm. STATE (default /tmp/vesicle-slurm)
# is set by VESICLE_SLURM_DIR. While the cluster runs, /etc/slurm/slurm.conf is a link to STATE's configuration
# (the script refuses to start where that file exists and is not its own link).
set -euo pipefail

STATE=${VESICLE_SLURM_DIR:-/tmp/vesicle-slurm}
CONF=$STATE/slurm.conf
SYSCONF=/etc/slurm/slurm.conf
export SLURM_CONF=$CONF

die() { echo "slurm-single-node: $*" >&2; exit 1; }

need() {
  for exe in munged slurmctld slurmd sinfo sbatch squeue scontrol; do
    command -v "$exe" >/dev/null || [ -x "/usr/sbin/$exe" ] ||
      die "$exe not found: apt-get install -y slurm-wlm munge"
  done
  [ "$(id -u)" = 0 ] || die "run as root (slurmd starts jobs as their users)"
}

write_conf() {
  local host cpus mem
  host=$(hostname -s)
  cpus=$(nproc)
  # 90% of the memory, and at least 16 GB: the CPU profile asks 8 GB for a run, and memory is not a consumable
  # resource here (CR_CPU, no cgroups), so a small CI machine must not refuse the request; config_overrides keeps
  # slurmd from draining a node that has less than this
  mem=$(awk '/MemTotal/ {m = $2 / 1024 * 0.9; printf "%d", (m > 16384 ? m : 16384)}' /proc/meminfo)
  mkdir -p "$STATE/ctld" "$STATE/spool"
  cat >"$CONF" <<EOF
# written by .ci/slurm-single-node.sh: one node, no cgroups, no accounting database
ClusterName=vesicle-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$STATE/ctld
SlurmdSpoolDir=$STATE/spool
SlurmctldPidFile=$STATE/slurmctld.pid
SlurmdPidFile=$STATE/slurmd.pid
SlurmctldLogFile=$STATE/slurmctld.log
SlurmdLogFile=$STATE/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
ReturnToService=2
MinJobAge=600
SlurmdTimeout=60
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=cpu Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
}

alive() { [ -f "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

start() {
  need
  mkdir -p "$STATE"
  touch "$STATE/started"  # kept across starts: stop stops what any start started
  write_conf
  # srun inside a job does not see the submitter's SLURM_CONF (the job steps of the Snakemake executor failed with
  # "Could not establish a configuration source"), so the configuration goes where every client looks for it,
  # unless this machine has a SLURM configuration of its own
  if [ -L "$SYSCONF" ] && [ "$(readlink "$SYSCONF")" = "$CONF" ]; then
    :
  elif [ -e "$SYSCONF" ]; then
    die "$SYSCONF exists: this machine has a SLURM configuration; not touching it"
  else
    mkdir -p "$(dirname "$SYSCONF")"
    ln -s "$CONF" "$SYSCONF"
  fi
  if ! pgrep -x munged >/dev/null; then
    [ -s /etc/munge/munge.key ] || {
      dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 2>/dev/null
      chown munge:munge /etc/munge/munge.key
      chmod 400 /etc/munge/munge.key
    }
    install -d -o munge -g munge -m 755 /run/munge
    # munged runs as munge and cannot write into STATE: its pid file goes beside its socket
    runuser -u munge -- /usr/sbin/munged --pid-file=/run/munge/vesicle-munged.pid
    ln -sf /run/munge/vesicle-munged.pid "$STATE/munged.pid"
    echo munged >>"$STATE/started"
  fi
  for daemon in slurmctld slurmd; do
    if alive "$STATE/$daemon.pid"; then
      continue
    fi
    "/usr/sbin/$daemon" -f "$CONF"
    echo "$daemon" >>"$STATE/started"
  done
  local host state
  host=$(hostname -s)
  for _ in $(seq 60); do
    state=$(sinfo -h -n "$host" -o %T 2>/dev/null || true)
    case $state in
      idle*) echo "slurm-single-node: node $host idle (SLURM_CONF=$CONF)"; return 0 ;;
      down* | drain*) scontrol update nodename="$host" state=resume 2>/dev/null || true ;;
    esac
    sleep 1
  done
  echo "slurm-single-node: node $host not idle after 60 s (state: ${state:-none}); logs in $STATE" >&2
  tail -n 20 "$STATE"/slurmctld.log "$STATE"/slurmd.log >&2 || true
  exit 1
}

stop() {
  [ -f "$STATE/started" ] || { echo "slurm-single-node: nothing started from $STATE"; return 0; }
  local daemon pidfile pid
  # the reverse order of start: slurmd, slurmctld, then munged
  for daemon in $(tac "$STATE/started"); do
    pidfile=$STATE/$daemon.pid
    if alive "$pidfile"; then
      pid=$(cat "$pidfile")
      kill "$pid"
      for _ in $(seq 30); do kill -0 "$pid" 2>/dev/null || break; sleep 0.5; done
      if kill -0 "$pid" 2>/dev/null; then
        echo "slurm-single-node: $daemon ($pid) did not stop in 15 s" >&2
      else
        echo "slurm-single-node: stopped $daemon ($pid)"
      fi
    fi
  done
  rm -f "$STATE/started"
  if [ -L "$SYSCONF" ] && [ "$(readlink "$SYSCONF")" = "$CONF" ]; then
    rm -f "$SYSCONF"
  fi
}

case ${1:-} in
  start) start ;;
  stop) stop ;;
  status) sinfo -N -l && squeue ;;
  *) die "usage: $0 start|stop|status" ;;
esac
